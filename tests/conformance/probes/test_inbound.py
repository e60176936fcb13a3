"""A probe's socket times each datagram by when it reached the socket (D-RSP-26, D-RCTP-33)."""

from __future__ import annotations

import asyncio
import json
import socket
import time
from pathlib import Path

from support.processes import run_command

from rcmlconf.conformance.probes.inbound import Inbound, arrival_clock
from rcmlconf.conformance.transcript import Address

HOLD = 0.3
#: How far the wall clock and the loop's may disagree when read one after the other.
CLOCKS = 0.005


def test_a_datagram_read_late_keeps_the_time_it_came() -> None:
    """The loop is held after the datagram comes: its time is from before the hold, and the
    bytes and source are as sent."""

    async def main() -> tuple[float, float, float, list[tuple[bytes, Address]]]:
        loop = asyncio.get_running_loop()
        got: list[tuple[bytes, Address, float]] = []

        def arrived(data: bytes, source: Address, at: float) -> None:
            got.append((data, source, at))

        transport, _ = await loop.create_datagram_endpoint(
            lambda: Inbound(arrived), local_addr=("127.0.0.1", 0)
        )
        try:
            with socket.socket(type=socket.SOCK_DGRAM) as sender:
                sender.bind(("127.0.0.1", 0))
                # Linux turns stamping on for the whole system in deferred work, the first time
                # a socket asks: a datagram before that runs has no stamp. One goes first.
                deadline = loop.time() + 5
                while not got and loop.time() < deadline:
                    sender.sendto(b"warm", transport.get_extra_info("sockname"))
                    await asyncio.sleep(0.05)
                got.clear()
                sent_at = loop.time()
                sender.sendto(b"late", transport.get_extra_info("sockname"))
                time.sleep(HOLD)  # the loop is held: nothing reads the socket
                held_until = loop.time()
                deadline = loop.time() + 5
                while not got and loop.time() < deadline:
                    await asyncio.sleep(0.01)
                source = sender.getsockname()
        finally:
            transport.close()
        assert got, "no datagram came within 5 s"
        data, came_from, at = got[0]
        return sent_at, at, held_until, [(data, came_from), (b"late", source)]

    sent_at, at, held_until, pair = asyncio.run(main())
    assert pair[0] == pair[1]
    # The kernel's stamp is on the wall clock: moved onto the loop's, it may come out a few
    # microseconds before the send.
    assert sent_at - CLOCKS <= at < held_until - HOLD / 2


def test_the_run_report_says_which_clock_timed_the_datagrams(tmp_path: Path) -> None:
    """Linux stamps datagrams: the JSON report says "kernel", and no notice of the loop's clock
    is printed (D-RSP-26, D-RCTP-33)."""
    assert arrival_clock() == ("kernel", "")
    report = tmp_path / "run.json"
    done = run_command("run", "--only", "rsp/session/welcome", "--json", str(report))
    assert done.returncode == 0, done.stderr
    assert "timed when the harness reads them" not in done.stderr
    assert json.loads(report.read_text())["settings"]["arrival_clock"] == "kernel"
