"""A case marked `exclusive` (rctp/session/peer-floors: D-RCTP-32's floors count every connection
of the harness's address) runs after the run's other cases, with none of them in flight, in each
of --repeat's runs; on the embedded reference, over real sockets."""

from __future__ import annotations

import asyncio

from rcmlconf.conformance.ics import EVERYTHING
from rcmlconf.conformance.registry import all_cases
from rcmlconf.conformance.runner import RunOptions, run_cases
from rcmlconf.conformance.targets import embedded_reference
from rcmlconf.conformance.verdicts import Result, Verdict

FLOORS = "rctp/session/peer-floors"
#: Cases beside it: concurrent ones and one of the server's serial lane.
OTHERS = ("rctp/session/connect-session-field", "rctp/msg/bare-lf", "rctp/session/bye-releases")
#: The whole run, at most (seconds).
BOUND = 90.0


def _run() -> list[Result]:
    async def scenario() -> list[Result]:
        async with embedded_reference(EVERYTHING.features) as target:
            cases = [all_cases()[case] for case in (FLOORS, *OTHERS)]
            return await run_cases(cases, target, RunOptions(repeat=2))

    return asyncio.run(asyncio.wait_for(scenario(), BOUND))


def test_an_exclusive_case_runs_alone_after_the_others_of_its_run() -> None:
    assert all_cases()[FLOORS].exclusive
    assert not any(all_cases()[case].exclusive for case in OTHERS)
    results = _run()
    assert {(r.case, r.verdict) for r in results} == {
        (case, Verdict.PASS) for case in (FLOORS, *OTHERS)
    }, results
    alone = {r.run: r for r in results if r.case == FLOORS}
    for result in results:
        if result.case == FLOORS:
            continue
        # Ended before its run's exclusive case started; started after the last run's ended.
        assert result.ended <= alone[result.run].ended - alone[result.run].duration, result
        if result.run > 1:
            assert result.ended - result.duration >= alone[result.run - 1].ended, result
