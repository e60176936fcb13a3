"""`run --role client --client-command` with hostile clients side by side (issue 27, point 3): one
that CONNECTs a path of no case, one that sends nothing (from a child of the process started),
one that sends garbage and one that opens 500 connections, each in a case of its own, beside a
case whose client is the reference one.
Each case judges the client started for it (D-RCTP-31): no case says no client connected, the
good clients' cases pass, and the run ends by itself. Before, a connection that named no case
went to the case that began last, and the flood filled a cap shared by every case."""

from __future__ import annotations

import asyncio
import json
import shlex
import sys
from pathlib import Path
from urllib.parse import urlsplit

import pytest
from support import hostile_clients
from support.processes import BOUND, free_pair, run_command

from rcmlconf.conformance.command import Command
from rcmlconf.conformance.probes.clients import HARNESS_RCML, ClientListener
from rcmlconf.conformance.transcript import Transcript
from rcmlconf.conformance.verdicts import Failed
from rcmlconf.validate.validator import load_robot

HOSTILE = {
    "rctp/client/connect-first": "elsewhere",
    "rctp/client/missing-cseq": "forked-silent",
    "rctp/client/wrong-version": "garbage",
    "rctp/client/cseq-twice": "flood",
}
GOOD = ("rctp/client/answers-bye",)


def _command(modes: dict[str, str]) -> str:
    script = [sys.executable, hostile_clients.__file__, "{url}"]
    return shlex.join(script + [f"{case}={mode}" for case, mode in modes.items()])


def test_each_case_judges_its_own_hostile_client_and_the_others_pass(tmp_path: Path) -> None:
    port = free_pair()
    report = tmp_path / "run.json"
    only = [word for case in (*HOSTILE, *GOOD) for word in ("--only", case)]
    done = run_command(
        "run", "--role", "client", "--listen", str(port), *only,
        "--client-command", _command(HOSTILE), "--timeout-scale", "0.5", "--json", str(report),
    )  # fmt: skip
    assert done.returncode == 1, done.stderr  # run_command: it ended, with no traceback
    results = {r["case"]: r for r in json.loads(report.read_text())["results"]}
    assert set(results) == {*HOSTILE, *GOOD}
    for case in GOOD:
        assert results[case]["verdict"] == "pass", results[case]
    for case, mode in HOSTILE.items():
        result = results[case]
        reason = str(result["reason"])
        exchange = " ".join(str(entry["summary"]) for entry in result["exchange"])
        assert result["verdict"] == "fail", (mode, result)
        assert "no client connected" not in reason, reason
        assert "harness fault" not in reason, reason
        assert "a client connected from" in exchange, (mode, exchange)
        # Its own client's report: the command started on this case's URL.
        assert f"/{case} " in exchange.split("client command ", 1)[1], (mode, exchange)
    assert "CONNECT /no/such/case" in results["rctp/client/connect-first"]["reason"]
    assert "connected and sent nothing" in results["rctp/client/missing-cseq"]["reason"]
    assert "grammar" in results["rctp/client/wrong-version"]["reason"]
    flood = results["rctp/client/cseq-twice"]
    assert "expected an answer" in flood["reason"]  # to the case's request: it answers nothing
    assert any("were closed unread" in str(e["summary"]) for e in flood["exchange"]), flood


def test_a_flood_fills_its_own_case_and_the_next_client_is_its_own_case_s() -> None:
    """The other case's client starts once the flood has been closed past the cap, and CONNECTs
    a path of no case: its own process still makes it its case's."""
    flooding, other = "rctp/client/cseq-twice", "rctp/client/answers-bye"

    async def scenario() -> None:
        loop = asyncio.get_running_loop()
        command = Command(_command({flooding: "flood", other: "elsewhere"}))
        robot = load_robot(HARNESS_RCML)
        listener = ClientListener(
            robot,
            HARNESS_RCML.read_bytes(),
            summon=command,
            stop=command.stop,
            owners=command.owners,
        )
        await listener.start("127.0.0.1", 0)
        try:
            listener.plan([flooding, other])
            assert await listener.arrival(flooding, BOUND) is None
            flood = command.runs[listener.url(flooding)]
            deadline = loop.time() + BOUND
            while not any(line.startswith("flood:") for line in flood.tail):
                assert loop.time() < deadline, "the flood did not end"
                await asyncio.sleep(0.02)
            assert await listener.arrival(other, BOUND) is None
            probe = await listener.accept(other, Transcript(), BOUND)
            assert (await probe.next_request()).target == "/no/such/case"
            report = listener.finish(flooding)
            assert any("were closed unread" in line for line in report), report
        finally:
            await listener.close()
            await command.close()

    asyncio.run(asyncio.wait_for(scenario(), BOUND))


def test_what_nothing_attributes_goes_to_the_first_case_still_waiting_for_a_connection() -> None:
    """In-process clients have no process to tell whose they are (D-RCTP-31's fallback). The
    first case begins, then the last, whose client CONNECTs it; then the first case's client
    sends garbage: the first case gets it, not the case that began last."""
    first, last = "rctp/client/cseq-twice", "rctp/client/answers-bye"
    go = asyncio.Event()

    async def client(url: str) -> None:
        split = urlsplit(url)
        if split.path != f"/{last}":
            await go.wait()
        _, writer = await asyncio.open_connection(split.hostname, split.port)
        hello = f"CONNECT {split.path} RCTP/2.0\r\nCSeq: 1\r\n\r\n".encode()
        writer.write(hello if split.path == f"/{last}" else hostile_clients.GARBAGE)
        await asyncio.sleep(BOUND)  # until the listener closes

    async def scenario() -> None:
        listener = ClientListener(
            load_robot(HARNESS_RCML), HARNESS_RCML.read_bytes(), summon=client
        )
        await listener.start("127.0.0.1", 0)
        try:
            listener.plan([first, last])
            waiting = asyncio.ensure_future(listener.arrival(first, 5.0))
            await asyncio.sleep(0)  # the first case begins first
            assert await listener.arrival(last, BOUND) is None
            go.set()
            assert await waiting is None
            own = await listener.accept(last, Transcript(), BOUND)
            assert (await own.next_request()).target == f"/{last}"
            garbled = await listener.accept(first, Transcript(), BOUND)
            with pytest.raises(Failed, match="grammar"):
                await garbled.next_request()
        finally:
            await listener.close()

    asyncio.run(asyncio.wait_for(scenario(), BOUND))
