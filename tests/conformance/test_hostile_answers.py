"""Servers that answer out of place fail, whatever case reads the answer (D-RCTP-6, R-RCTP-3,
R-RCTP-5, D-RCTP-10): each hostile server of support.hostile_answers is the embedded reference
behind a proxy, and a few server cases run through it. Before, a server answering every request
twice passed rctp/priv/acquire-again: the repeated answer to CONNECT was taken for ACQUIRE's."""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses

from support.control_proxy import ControlProxy
from support.hostile_answers import HOSTILE
from support.server_cases import run_through

from rcmlconf.conformance.context import Context
from rcmlconf.conformance.ics import EVERYTHING
from rcmlconf.conformance.probes.control import ControlProbe
from rcmlconf.conformance.registry import Case
from rcmlconf.conformance.roles import Role
from rcmlconf.conformance.runner import RunOptions, run_case
from rcmlconf.conformance.targets import embedded_reference
from rcmlconf.conformance.transcript import Transcript
from rcmlconf.conformance.verdicts import Failed, Result, Verdict
from rcmlconf.rctp.messages import Response
from rcmlconf.rctp.reader import MessageReader

BOUND = 30.0
#: The cases run through each server, quick ones that read several answers.
ONLY = ("rctp/priv/acquire-again", "rctp/msg/pipelined", "rctp/session/timeout-bye")
#: What each hostile server's run fails with: case -> requirement and the words of the reason.
FAILS = {
    "duplicate": {
        "rctp/priv/acquire-again": (
            "R-RCTP-3",
            "expected the answer to CSeq 2 (ACQUIRE /); got 200 OK with CSeq 1 (CONNECT /rover,"
            " answered already)",
        ),
        # The case judges its answers' CSeq under its own requirement.
        "rctp/msg/pipelined": ("R-RCTP-5", "expected the answer to CSeq 2 (CONNECT /rover)"),
        "rctp/msg/pipelined-mixed": ("R-RCTP-5", "got 200 OK with CSeq 1"),
        # It waits for the server's BYE, with nothing to answer.
        "rctp/session/timeout-bye": (
            "R-RCTP-3",
            "expected no response: no request waits for one (D-RCTP-10); got 200 OK with CSeq 1",
        ),
    },
    "unsolicited": {
        "rctp/priv/acquire-again": (
            "R-RCTP-3",
            "expected the answer to CSeq 2 (ACQUIRE /); got 200 OK with CSeq 4242",
        ),
        "rctp/msg/pipelined": ("R-RCTP-5", "CSeq 2 (CONNECT /rover); got 200 OK with CSeq 4242"),
        "rctp/msg/pipelined-mixed": ("R-RCTP-5", "got 200 OK with CSeq 4242"),
        "rctp/session/timeout-bye": ("R-RCTP-3", "no request waits for one (D-RCTP-10)"),
    },
    "wrong-cseq": dict.fromkeys(
        (*ONLY, "rctp/msg/pipelined-mixed"),
        ("R-RCTP-3", "expected the answer to CSeq 1 (CONNECT /rover); got 200 OK with CSeq 101"),
    ),
}


def _verdicts(results: list[Result]) -> dict[str, tuple[Verdict, str | None, str]]:
    return {r.case: (r.verdict, r.requirement, r.reason) for r in results}


def test_answers_out_of_place_fail_with_both_cseqs() -> None:
    async def scenario() -> dict[str, list[Result]]:
        async with embedded_reference(EVERYTHING.features) as target:
            runs = {"plain": await run_through(target, ControlProxy, *ONLY)}
            for name, proxy_of in HOSTILE.items():
                runs[name] = await run_through(target, proxy_of, *ONLY)
            return runs

    runs = asyncio.run(asyncio.wait_for(scenario(), BOUND))
    # Through a proxy that spoils nothing every case passes: what fails below is the spoiling.
    assert {r.verdict for r in runs.pop("plain")} == {Verdict.PASS}
    for name, results in runs.items():
        found = _verdicts(results)
        for case, (requirement, words) in FAILS[name].items():
            verdict, named, reason = found[case]
            assert (verdict, named) == (Verdict.FAIL, requirement), (name, case, reason)
            assert words in reason, (name, case, reason)


def test_a_wrong_answer_fails_a_case_that_took_it_for_something_else() -> None:
    """The runner gives the first answer out of place the last word: a case that swallowed it
    (as one that reads silence out of R-RCTP-5) still fails."""

    async def swallowing(ctx: Context) -> None:
        probe = await ctx.session()
        with contextlib.suppress(Failed):
            await probe.request("ACQUIRE", "/")
        await probe.request("RELEASE", "*")  # whatever it reads now, it is not judged again

    case = Case(
        id="test/swallowing",
        purpose="",
        requirements=("R-RCTP-33",),
        role=Role.SERVER,
        timeout=5.0,
        impairment=None,
        features=(),
        serial=False,
        run=swallowing,
    )

    async def scenario() -> Result:
        async with embedded_reference(EVERYTHING.features) as target:
            assert target.server is not None
            proxy = HOSTILE["duplicate"](target.server)
            try:
                through = dataclasses.replace(target, server=await proxy.start())
                return await run_case(case, through, RunOptions())
            finally:
                await proxy.close()

    result = asyncio.run(asyncio.wait_for(scenario(), BOUND))
    assert (result.verdict, result.requirement) == (Verdict.FAIL, "R-RCTP-3"), result.reason
    assert "CSeq 2 (ACQUIRE /)" in result.reason


def test_a_server_bye_before_any_session_is_refused_454() -> None:
    """D-RCTP-13: in idle only CONNECT is valid. A server that sends BYE before it answers the
    CONNECT gets 454 from the harness playing the client; once the session is open, 200."""
    answers: list[int] = []

    async def server(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        messages = MessageReader()
        session = "Session: abcdefgh12345678;timeout=60\r\n"
        writer.write(b"BYE * RCTP/2.0\r\nCSeq: 1\r\n\r\n")
        while len(answers) < 2 and (data := await reader.read(65536)):
            messages.feed(data)
            while (message := messages.next_message()) is not None:
                if isinstance(message, Response):
                    answers.append(message.status)
                    continue
                writer.write(
                    f"RCTP/2.0 200 OK\r\nCSeq: {message.headers.get('CSeq')}\r\n{session}\r\n"
                    f"BYE * RCTP/2.0\r\nCSeq: 2\r\n{session}\r\n".encode()
                    if message.method == "CONNECT"
                    else f"RCTP/2.0 200 OK\r\nCSeq: {message.headers.get('CSeq')}\r\n\r\n".encode()
                )
        writer.close()

    async def scenario() -> None:
        listening = await asyncio.start_server(server, "127.0.0.1", 0)
        address = listening.sockets[0].getsockname()[:2]
        probe = await ControlProbe.open(address, Transcript(), 2.0)
        assert (await probe.connect("/rover")).status == 200  # the first BYE answered first
        assert (await probe.request("READ", "/a")).status == 200  # the second BYE first
        probe.close()
        listening.close()

    asyncio.run(asyncio.wait_for(scenario(), BOUND))
    assert answers == [454, 200]
