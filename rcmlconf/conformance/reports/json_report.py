"""--json: the run as one JSON document: what ran against what, when, and every result with its
exchange as data. `run-report.schema.json` beside this module is its JSON Schema; `version`
grows by one whenever a field changes meaning or goes (a field added keeps it).

Version 2 (version 1 had no `started`/`duration`, and its `exchange` was the transcript's
display lines): `exchange` is a list of objects, see `exchange.exchange_json`; `left_out` says
what the bounded transcript left out of it (`exchange.left_out_json`). A run with --verify adds
`unstable`: each case whose runs gave different verdicts, with their counts (`stability`)."""

from __future__ import annotations

import datetime
import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from rcmlconf.conformance.registry import Case
from rcmlconf.conformance.reports.exchange import exchange_json, left_out_json
from rcmlconf.conformance.reports.summary import counts
from rcmlconf.conformance.stability import Unstable
from rcmlconf.conformance.transcript import Entry
from rcmlconf.conformance.verdicts import Result

VERSION = 2
#: The JSON Schema of the report, shipped in the package.
SCHEMA = Path(__file__).with_name("run-report.schema.json")
#: A transcript's line: its time, two spaces, the text (`Transcript.note`).
_TIMED = re.compile(r" *(\d+\.\d+)  (.*)", re.DOTALL)


def to_json(
    results: Sequence[Result],
    cases: Mapping[str, Case],
    target: str,
    settings: Mapping[str, Any],
    span: tuple[float, float],
    unstable: Sequence[Unstable] | None = None,
) -> dict[str, Any]:
    """`span`: when the run started and ended (time.time()). `unstable`: the judgement of
    --verify, None without it."""
    started, ended = span
    report = {
        "version": VERSION,
        "target": target,
        "started": _stamp(started),
        "duration": round(max(ended - started, 0.0), 3),
        "settings": dict(settings),
        "counts": {verdict.value: n for verdict, n in counts(results).items()},
        "results": [_result(r, cases[r.case]) for r in results],
    }
    if unstable is not None:
        report["unstable"] = [{"case": u.case, "verdicts": dict(u.counts())} for u in unstable]
    return report


def _stamp(at: float) -> str:
    return datetime.datetime.fromtimestamp(at, datetime.UTC).isoformat(timespec="milliseconds")


def _lines(lines: Sequence[str]) -> list[Entry]:
    """A result kept only as lines (a client case whose client never came: its command's last
    words) as entries: each line's time if it has one (`Transcript.note`), else 0."""
    entries = []
    for line in lines:
        timed = _TIMED.fullmatch(line)
        at, text = (float(timed[1]), timed[2]) if timed else (0.0, line)
        entries.append(Entry(at, text=text))
    return entries


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
        "exchange": exchange_json(result.entries or _lines(result.exchange)),
        "left_out": left_out_json(result.entries),
        "used": list(result.used),
    }
