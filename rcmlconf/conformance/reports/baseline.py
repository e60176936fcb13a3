"""--baseline FILE: known failures, so that CI fails only on new ones. The file is either a list
of case IDs, one a line (`#` starts a comment), or a --json report of an earlier run, whose
failures and errors are taken.

Anything else is refused, with the line or result that is not one: a line that is no case ID
(`protocol/area/name`), JSON that is not such a report. An ID of the right form that names no
case of this version is not refused here: `unknown_ids` finds those, and `rcmlconf run` warns
(a case may have been renamed since the baseline was written)."""

from __future__ import annotations

import json
from collections.abc import Collection, Iterable
from dataclasses import replace
from pathlib import Path
from typing import Any, NoReturn

from rcmlconf.conformance.files import UnreadableFile, read_text, shown
from rcmlconf.conformance.registry import is_case_id
from rcmlconf.conformance.verdicts import Result, Verdict
from rcmlconf.errors import RcmlconfError
from rcmlconf.wording import one_line, shorten

_FAILING = (Verdict.FAIL.value, Verdict.ERROR.value)
_VERDICTS = frozenset(v.value for v in Verdict)
#: More than the report of the whole suite run 1,000 times over (--repeat's most) with room.
MOST_BASELINE_BYTES = 256 << 20
_REPORT = "a report of `rcmlconf run --json`"


class BaselineError(RcmlconfError):
    pass


def load_baseline(path: Path) -> frozenset[str]:
    """The IDs of the cases the baseline at `path` lists as known failures."""
    try:
        text = read_text(path, MOST_BASELINE_BYTES, "a baseline")
    except UnreadableFile as error:
        raise BaselineError(str(error)) from None
    try:
        document = json.loads(text)
    except ValueError as error:
        if text.lstrip().startswith(("{", "[")):
            _fail(path, f"not {_REPORT}: {error}")
        return _listed(path, text)
    return _reported(path, document)


def unknown_ids(known: Iterable[str], cases: Collection[str]) -> list[str]:
    """The IDs of a baseline that name no case, sorted."""
    return sorted(set(known) - set(cases))


def mark_known(results: Iterable[Result], known: frozenset[str]) -> list[Result]:
    """The results, failures and errors of a listed case marked known."""
    return [
        replace(r, known=True) if r.case in known and r.verdict.value in _FAILING else r
        for r in results
    ]


def _listed(path: Path, text: str) -> frozenset[str]:
    found = set()
    for number, line in enumerate(text.splitlines(), 1):
        entry = line.split("#", 1)[0].strip()
        if not entry:
            continue
        if not is_case_id(entry):
            _fail(
                path,
                f"{shorten(entry)!r} is not a case ID (protocol/area/name, as `rcmlconf cases`"
                " lists them)",
                number,
            )
        found.add(entry)
    return frozenset(found)


def _reported(path: Path, document: Any) -> frozenset[str]:
    results = document.get("results") if isinstance(document, dict) else None
    if not isinstance(results, list):
        _fail(path, f"not {_REPORT} (JSON, but not an object with a list of results)")
    found = set()
    for index, result in enumerate(results):
        case = result.get("case") if isinstance(result, dict) else None
        verdict = result.get("verdict") if isinstance(result, dict) else None
        if not (isinstance(case, str) and is_case_id(case) and verdict in _VERDICTS):
            _fail(
                path,
                f"results[{index}] is not a result of `rcmlconf run --json` (an object with a"
                f" case ID and a verdict): {shorten(json.dumps(result))}",
            )
        if verdict in _FAILING:
            found.add(case)
    return frozenset(found)


def _fail(path: Path, why: str, line: int | None = None) -> NoReturn:
    where = shown(path) if line is None else f"{shown(path)}:{line}"
    raise BaselineError(one_line(f"{where}: {why}"))
