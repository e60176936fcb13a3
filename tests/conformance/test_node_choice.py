"""Cases pick the node that makes their check decisive, and say so where the robot has none
(issue 16: node choice). Run on the reference server of robots built for it."""

from __future__ import annotations

import asyncio
from pathlib import Path

from support.robots import TESTBOT, robot
from support.servers import serving

from rcmlconf.conformance.context import Context
from rcmlconf.conformance.ics import EVERYTHING
from rcmlconf.conformance.picks import writable
from rcmlconf.conformance.registry import all_cases
from rcmlconf.conformance.runner import PARTLY, RunOptions, run_cases
from rcmlconf.conformance.targets import Target
from rcmlconf.conformance.verdicts import Result, Verdict

ONE_BYTE = Path(__file__).parent / "robots" / "one-byte.rcml"
WRITE_ONLY_FIRST = Path(__file__).parent / "robots" / "write-only-first.rcml"
WRITE_ONLY = Path(__file__).parent / "robots" / "write-only.rcml"
BOUND = 30.0


def run_on(rcml: Path, *ids: str) -> dict[str, Result]:
    async def scenario() -> list[Result]:
        async with serving(rcml) as server:
            model = robot(rcml)
            target = Target(
                server=("127.0.0.1", server.port),
                robot=model,
                site_path=model.site.path,
                features=EVERYTHING.features,
            )
            return await run_cases([all_cases()[i] for i in ids], target, RunOptions())

    return {r.case: r for r in asyncio.run(asyncio.wait_for(scenario(), BOUND))}


def test_write_short_needs_a_value_of_two_bytes_or_more() -> None:
    """One byte short of a 1-byte value is an empty body, which D-RCTP-15 answers 411: on a robot
    whose writable nodes are all one byte, write-short cannot check 422 and says so; it does not
    fail a server that answers 411 as write-no-length requires."""
    results = run_on(ONE_BYTE, "rctp/node/write-short", "rctp/node/write-no-length")
    short = results["rctp/node/write-short"]
    assert short.verdict is Verdict.NOT_APPLICABLE, short
    assert "2 bytes or more" in short.reason
    assert results["rctp/node/write-no-length"].verdict is Verdict.PASS


def test_refused_writes_pick_a_node_that_can_be_read_back() -> None:
    """A refused WRITE must change nothing (R-RCTP-28): the cases write a node they can read
    before and after, where the robot has one, and pass on the reference."""
    ids = ("rctp/node/write-short", "rctp/node/write-long", "rctp/node/write-media-type")
    results = run_on(TESTBOT, *ids)
    assert {r.verdict for r in results.values()} == {Verdict.PASS}, results


def test_writable_picks_a_node_that_can_be_read_back_first() -> None:
    """The first writable node of WRITE_ONLY_FIRST is write-only; the pick passes it by for the
    readable one, which alone can show what a WRITE changed (R-RCTP-28)."""

    async def picked() -> str:
        target = Target(robot=robot(WRITE_ONLY_FIRST))
        ctx = Context(all_cases()["rctp/node/write-short"], target)
        return writable(ctx).path

    assert asyncio.run(picked()) == "/panel/controls/level"

    # A case whose robot has no readable writable node still gets the write-only one.
    async def only() -> str:
        target = Target(robot=robot(WRITE_ONLY_FIRST))
        ctx = Context(all_cases()["rctp/node/write-short"], target)
        return writable(ctx, lambda node: node.name == "command").path

    assert asyncio.run(only()) == "/panel/controls/command"


def test_a_result_says_which_nodes_the_case_used() -> None:
    """`run -v` and --json show them: here the readable, writable node write-short picked."""
    results = run_on(WRITE_ONLY_FIRST, "rctp/node/write-short", "rctp/node/write-long")
    for result in results.values():
        assert result.used == ("/panel/controls/level",), result


def test_a_pass_that_could_check_part_only_says_which_part() -> None:
    """No node of WRITE_ONLY can be read: a refused WRITE's 'changed nothing' is out of reach, and
    the pass says so instead of passing silently."""
    results = run_on(WRITE_ONLY, "rctp/node/write-long", "rctp/node/write-out-of-range")
    for result in results.values():
        assert result.verdict is Verdict.PASS, result
        assert result.reason.startswith(PARTLY), result
        assert "/panel/controls/command cannot be read" in result.reason
