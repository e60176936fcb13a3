"""--json: the run as one JSON document (version 1): what ran against what, every result."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from rcmlconf.conformance.registry import Case
from rcmlconf.conformance.reports.summary import counts
from rcmlconf.conformance.verdicts import Result

VERSION = 1


def to_json(
    results: Sequence[Result],
    cases: Mapping[str, Case],
    target: str,
    settings: Mapping[str, Any],
) -> dict[str, Any]:
    return {
        "version": VERSION,
        "target": target,
        "settings": dict(settings),
        "counts": {verdict.value: n for verdict, n in counts(results).items()},
        "results": [_result(r, cases[r.case]) for r in results],
    }


def _result(result: Result, case: Case) -> dict[str, Any]:
    return {
        "case": result.case,
        "run": result.run,
        "verdict": result.verdict.value,
        "known": result.known,
        "duration": round(result.duration, 4),
        "purpose": case.purpose,
        "requirements": list(case.requirements),
        "role": case.role.value,
        "reason": result.reason,
        "requirement": result.requirement,
        "expected": list(result.expected),
        "actual": result.actual,
        "exchange": list(result.exchange),
        "used": list(result.used),
    }
