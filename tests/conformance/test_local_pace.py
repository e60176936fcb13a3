"""The rsp/local cases of the pace (rcmlconf.conformance.cases.rsp_local.pace), of an old event ID,
and the idle keep-alive's check of a T changed without PERIOD: they pass the embedded reference's
local system and an independent one (tests/foreign/rsp_local, written from specs/ alone), and fail
that independent one when it makes a fault they are aimed at (or a copy of the reference made to
make one it has none of), naming the requirement it breaks. Real processes on loopback, as in
test_local_receiving."""

from __future__ import annotations

from pathlib import Path

import pytest
from conformance.test_local_receiving import run, run_foreign, verdicts
from support.mutants import mutated

CASES = [
    "rsp/local/welcome-opens",
    "rsp/local/lost-link-goes-on",
    "rsp/local/period-doubles",
    "rsp/local/event-old-id",
    "rsp/local/idle-keep-alive",
    "rsp/local/kept-until-bye",
]
#: The fault of the independent local system a case is aimed at, and what it must fail with.
AIMED = {
    "rsp/local/period-doubles": ("welcome-period-ignored", "R-RSP-43"),
    "rsp/local/event-old-id": ("event-no-dedup", "R-RSP-25"),
}


def test_the_cases_pass_the_embedded_reference(tmp_path: Path) -> None:
    results = run(tmp_path, *(option for case in CASES for option in ("--only", case)))
    assert verdicts(results) == dict.fromkeys(CASES, "pass"), results


def test_the_cases_pass_an_independent_local_system(tmp_path: Path) -> None:
    results = run_foreign(tmp_path, CASES)
    assert verdicts(results) == dict.fromkeys(CASES, "pass"), results


@pytest.mark.parametrize("case", AIMED)
def test_each_case_fails_the_local_system_making_its_fault(tmp_path: Path, case: str) -> None:
    fault, requirement = AIMED[case]
    result = run_foreign(tmp_path, [case], fault)[case]
    assert (result["verdict"], result["requirement"]) == ("fail", requirement), result


def test_a_local_system_ending_its_run_without_bye_fails_kept_until_bye(tmp_path: Path) -> None:
    """The embedded reference, in a copy, closing its session at the end of D-RSP-24's run
    without BYE (bench/mutation_survivors.md's local.py 189): its packets stop, and nothing
    ended the session (D-RSP-12)."""
    copy = mutated(
        tmp_path, "rsp/session/local.py", ("self._bye(ByeReason.CLOSED, now)", "pass  # silently")
    )
    case = "rsp/local/kept-until-bye"
    result = run(tmp_path, "--only", case, python=copy)[case]
    assert (result["verdict"], result["requirement"]) == ("fail", "R-RSP-42"), result
