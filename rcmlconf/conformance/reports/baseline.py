"""--baseline FILE: known failures, so that CI fails only on new ones. The file is either a list
of case IDs, one a line (`#` starts a comment), or a --json report of an earlier run, whose
failures and errors are taken."""

from __future__ import annotations

import json
from collections.abc import Iterable
from dataclasses import replace
from pathlib import Path

from rcmlconf.conformance.verdicts import Result, Verdict
from rcmlconf.errors import RcmlconfError

_FAILING = (Verdict.FAIL.value, Verdict.ERROR.value)


class BaselineError(RcmlconfError):
    pass


def load_baseline(path: Path) -> frozenset[str]:
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as error:
        raise BaselineError(f"{path}: {error}") from None
    if text.lstrip().startswith("{"):
        try:
            report = json.loads(text)
            return frozenset(
                str(r["case"]) for r in report["results"] if r.get("verdict") in _FAILING
            )
        except (ValueError, KeyError, TypeError) as error:
            raise BaselineError(f"{path}: not a report of `rcmlconf run --json`: {error}") from None
    return frozenset(
        line.split("#", 1)[0].strip() for line in text.splitlines() if line.split("#", 1)[0].strip()
    )


def mark_known(results: Iterable[Result], known: frozenset[str]) -> list[Result]:
    """The results, failures and errors of a listed case marked known."""
    return [
        replace(r, known=True) if r.case in known and r.verdict.value in _FAILING else r
        for r in results
    ]
