"""What a robot case waits for that the robot must send (an ACK, an UPLINK that took a DOWNLINK,
the answer to a HELLO, a monitor reporting the value written: `awaited.must_come`; the UPLINKs of
rsp/value's range cases) is judged as D-RSP-26 judges what must come by a bound, on the embedded
reference in this process. A robot stalled, its datagrams held back past the case's window, while
the harness's loop was held as long (a robot short of CPU beside the harness, as in CI): the case
is inconclusive, where it used to fail. Stalled as long with the loop free (a robot in another
process, late), or never sending it: the case fails, naming the requirement. What the robot may
send or not (the UPLINK showing a memory command left the buffer: `awaited.may_come`) is waited
for as much longer as the harness's loop was held."""

from __future__ import annotations

import asyncio
import time
from collections.abc import Callable

import pytest
from support.embedded import run_embedded

from rcmlconf.conformance.loopwatch import LoopWatch
from rcmlconf.conformance.probes.rsp_probe import QUIET
from rcmlconf.conformance.registry import all_cases
from rcmlconf.conformance.verdicts import Verdict
from rcmlconf.errors import ProtocolError
from rcmlconf.reference.datagrams import Address, DataSocket
from rcmlconf.rsp.codec import Header, PacketType, pull_header

#: Seconds past the case's window the robot's datagrams are held back, about.
PAST = 0.1
#: Seconds rsp/value/out-of-range's robot sends nothing, from the UPLINK that took the last
#: DOWNLINK in range (#10): the ten periods of its values out of range, and more.
SILENT = 1.0

Pick = Callable[[Header], bool]


def _first_ack(header: Header) -> bool:
    return header.type is PacketType.ACK


def _took(sequence: int) -> Pick:
    """An UPLINK that took the case's DOWNLINK numbered `sequence` (its HELLO is 0)."""
    return lambda header: header.type is PacketType.UPLINK and header.last_received >= sequence


def _welcome(header: Header) -> bool:
    return header.type is PacketType.WELCOME


def _left_buffer() -> Pick:
    """The first UPLINK with more free buffers than the first ACK gave: the memory command that
    ACK took has left the buffer, its execution begun (D-RSP-19)."""
    acked: list[int] = []

    def pick(header: Header) -> bool:
        if header.type is PacketType.ACK:
            acked.append(header.buffer)
        return header.type is PacketType.UPLINK and bool(acked) and header.buffer > acked[0]

    return pick


def _wait(case: str) -> float:
    """The probe's wait in `case` (`Context.wait`): the window of most of what it waits for."""
    return all_cases()[case].timeout / 3


#: case, the datagram the robot stalls at (or never sends), the case's window for it (seconds),
#: and the requirement its failure names.
CASES = [
    ("rsp/value/over-size", _first_ack, _wait("rsp/value/over-size"), "R-RSP-18"),
    ("rsp/header/outside-window", _first_ack, _wait("rsp/header/outside-window"), "R-RSP-26"),
    ("rsp/header/last-received", _took(3), QUIET, "R-RSP-15"),
    # rsp_buffer.take
    ("rsp/reliable/command-reacked", _first_ack, _wait("rsp/reliable/command-reacked"), "R-RSP-26"),
    # the endpoint's commands acknowledged (rsp_reliable._acknowledged)
    (
        "rsp/reliable/commands-under-loss",
        _first_ack,
        _wait("rsp/reliable/commands-under-loss"),
        "R-RSP-26",
    ),
    # rsp_raw.RawSession.expect_welcome
    ("rsp/session/welcome", _welcome, _wait("rsp/session/welcome"), "R-RSP-20"),
    # rsp_driven.Driven.shown: every UPLINK from the first DOWNLINK's, the effector's value in it
    ("rsp/payload/effector-applied", _took(1), _wait("rsp/payload/effector-applied"), "R-RSP-34"),
]
IDS = [case for case, *_ in CASES]


def _stall(monkeypatch: pytest.MonkeyPatch, pick: Pick, *, held: float, then: float) -> None:
    """At the first datagram `pick` selects, the robot holds the harness's loop `held` seconds
    and sends nothing for `then` seconds more (it sends what it made then, in order)."""
    send = DataSocket.sendto
    waiting: list[tuple[DataSocket, bytes, Address | None]] = []
    until: list[float] = []

    def release() -> None:
        for socket, data, addr in waiting:
            send(socket, data, addr)
        waiting.clear()

    def sendto(socket: DataSocket, data: bytes, addr: Address | None = None) -> None:
        loop = asyncio.get_running_loop()
        if not until and _picked(pick, data):
            time.sleep(held)
            until.append(loop.time() + then)
            loop.call_at(until[0], release)
        if until and loop.time() < until[0]:
            waiting.append((socket, data, addr))
            return
        send(socket, data, addr)

    monkeypatch.setattr(DataSocket, "sendto", sendto)


def _never(monkeypatch: pytest.MonkeyPatch, pick: Pick) -> None:
    """The robot never sends what `pick` selects, and sends all else."""
    send = DataSocket.sendto

    def sendto(socket: DataSocket, data: bytes, addr: Address | None = None) -> None:
        if not _picked(pick, data):
            send(socket, data, addr)

    monkeypatch.setattr(DataSocket, "sendto", sendto)


def _unloaded(monkeypatch: pytest.MonkeyPatch) -> None:
    """A machine that holds nothing: the loop watch sees no hold, whatever this one's load."""
    monkeypatch.setattr(LoopWatch, "held", lambda _, since: 0.0)
    monkeypatch.setattr(LoopWatch, "total", lambda _, since: 0.0)


def _picked(pick: Pick, data: bytes) -> bool:
    try:
        return pick(pull_header(data))
    except ProtocolError:
        return False


@pytest.mark.parametrize(("case", "pick", "window", "requirement"), CASES, ids=IDS)
def test_a_robot_stalled_with_the_harness_is_inconclusive(
    monkeypatch: pytest.MonkeyPatch, case: str, pick: Pick, window: float, requirement: str
) -> None:
    _stall(monkeypatch, pick, held=window, then=PAST)
    result = run_embedded(case)
    assert result.verdict is Verdict.INCONCLUSIVE, result
    assert "event loop was held" in result.reason, result


@pytest.mark.parametrize(("case", "pick", "window", "requirement"), CASES, ids=IDS)
def test_a_robot_stalled_alone_fails(
    monkeypatch: pytest.MonkeyPatch, case: str, pick: Pick, window: float, requirement: str
) -> None:
    _unloaded(monkeypatch)
    _stall(monkeypatch, pick, held=0.0, then=window + PAST)
    result = run_embedded(case)
    assert (result.verdict, result.requirement) == (Verdict.FAIL, requirement), result
    assert "it came" in (result.actual or ""), result  # the second window saw it, late


@pytest.mark.parametrize(("case", "pick", "window", "requirement"), CASES, ids=IDS)
def test_a_robot_that_never_sends_it_fails(
    monkeypatch: pytest.MonkeyPatch, case: str, pick: Pick, window: float, requirement: str
) -> None:
    _unloaded(monkeypatch)
    _never(monkeypatch, pick)
    result = run_embedded(case)
    assert (result.verdict, result.requirement) == (Verdict.FAIL, requirement), result


@pytest.mark.parametrize(("held", "verdict"), [(SILENT, Verdict.INCONCLUSIVE), (0.0, Verdict.FAIL)])
def test_a_robot_silent_through_values_out_of_range(
    monkeypatch: pytest.MonkeyPatch, held: float, verdict: Verdict
) -> None:
    """No UPLINK while the case sends its values out of range: the monitor is not reported, as
    a robot that stopped at them would not report it (R-RSP-16), but a silence, which the loop
    held as long excuses (the silence then is the harness's as much as the robot's)."""
    if not held:
        _unloaded(monkeypatch)
    _stall(monkeypatch, _took(10), held=held, then=SILENT)
    result = run_embedded("rsp/value/out-of-range")
    assert result.verdict is verdict, result
    assert "no UPLINK" in result.reason, result


#: rsp_reliable._busy's case: it reads the free buffers once memory command #0 left the buffer,
#: and finds the buffer not held (R-RSP-31) when #1 is taken without a count below that.
BUSY = "rsp/reliable/memory-command-once"


def test_a_robot_stalled_with_the_harness_before_its_buffer_shows_it_busy_passes(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The UPLINK that shows #0 left the buffer (D-RSP-19) is held back past the case's wait for
    it (the quiet time) and the two periods after it, while the harness's loop was held longer:
    the case waits for it as much longer as the holds add up to (D-RSP-26), and reads the count
    after it, where it read the one before and failed."""
    _stall(monkeypatch, _left_buffer(), held=2 * QUIET, then=PAST)
    result = run_embedded(BUSY)
    assert result.verdict is Verdict.PASS, result


def test_a_robot_stalled_alone_before_its_buffer_shows_it_busy_fails(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """As long a stall with the loop free: the holds excuse nothing, and the count read before #0
    left is not held by #1."""
    _unloaded(monkeypatch)
    _stall(monkeypatch, _left_buffer(), held=0.0, then=QUIET + PAST)
    result = run_embedded(BUSY)
    assert (result.verdict, result.requirement) == (Verdict.FAIL, "R-RSP-31"), result
