"""What the rctp/stream, rctp/flow and rctp/clock cases share: a stream access chosen for what a
case needs of it, set up on a socket of the case's, played, and its DATA and FLOW judged
(specs/rctp-2.0.md §5 D-RCTP-18, D-RCTP-28, §6 D-RCTP-19 to D-RCTP-24).

Each case opens its own session and data-stream socket (`probes.stream`) and picks a stream
access by what the case needs of it — readable nodes and a `readInterval`, writable ones — so
that any robot can be tested; a robot without one makes the case not applicable.

Waits for something that must come are bounded by the case's answer wait; windows in which
nothing may come are short and fixed (`QUIET`, after `GRACE` for what was in flight), so that a
slow server may pass such a case wrongly, never fail it wrongly.
"""

from __future__ import annotations

import asyncio
import contextlib
import math
import time
from collections.abc import Callable

from rcmlconf.conformance.context import Context, outside_bounds
from rcmlconf.conformance.probes.control import ControlProbe
from rcmlconf.conformance.probes.stream import (
    Datagram,
    StreamProbe,
    StreamSetUp,
    answers,
    flow_text,
    open_stream,
)
from rcmlconf.conformance.verdicts import Failed, Inconclusive, NotApplicable
from rcmlconf.errors import ProtocolError
from rcmlconf.rcml.model import AccessNode, AccessType, DataNode, Permission
from rcmlconf.rctp.bodies import ValuesCodec
from rcmlconf.rctp.datastream import (
    DataPayload,
    Direction,
    FlowMessage,
    FlowPayload,
    HeartbeatRequest,
    Nack,
    NackReason,
    Payload,
    TimeoutSet,
    TimeoutSetAck,
    ntp_from_unix,
)
from rcmlconf.rctp.targets import format_target
from rcmlconf.values import Value

#: Seconds after a PAUSE or STOP is answered in which DATA sent before it may still arrive.
GRACE = 0.05
#: Seconds in which nothing may arrive (at least five intervals of the stream).
QUIET = 0.15
#: The most seconds of DATA a case measures.
MEASURE = 1.0
#: The longest readInterval a case that waits for DATA has time for.
SLOWEST = 0.25
#: D-RCTP-19: sequence numbers and request ids are 16-bit.
MODULO = 1 << 16
#: A FLOW operation no end knows (R-RCTP-53).
UNKNOWN_OPERATION = 0x7E
#: A payload type no end knows (R-RCTP-51).
UNKNOWN_TYPE = 0x7F


# -- choosing -------------------------------------------------------------------------------------


def readable_stream(
    ctx: Context, where: Callable[[AccessNode], bool] = lambda _: True
) -> AccessNode:
    """The stream access with readable nodes (and `where`) whose `readInterval` is shortest."""
    found = [
        a
        for a in ctx.robot.access_nodes()
        if a.type is AccessType.STREAM and a.readable() and a.read_interval and where(a)
    ]
    if not found:
        raise NotApplicable("the robot has no stream access with readable nodes")
    return min(found, key=lambda a: a.read_interval or 0.0)


def writable_stream(
    ctx: Context, where: Callable[[AccessNode], bool] = lambda _: True
) -> AccessNode:
    """A stream access with writable nodes and a `writeInterval` (and `where`)."""
    return ctx.access(
        AccessType.STREAM,
        Permission.WRITE,
        where=lambda a: bool(a.writable()) and bool(a.write_interval) and where(a),
    )


def has_data(datagram: Datagram, set_up: StreamSetUp) -> bool:
    """Whether a packet holds DATA of the set-up stream."""
    packet = datagram.packet
    return packet is not None and any(
        isinstance(p, DataPayload) and p.stream == set_up.stream for p in packet.payloads
    )


def interval_of(set_up: StreamSetUp) -> float:
    assert set_up.read_interval is not None  # `readable_stream` chose it so
    return set_up.read_interval


def quiet_for(set_up: StreamSetUp) -> float:
    """A window in which a stream that must send nothing would have sent five times (or for a
    second, for a slow one)."""
    return max(QUIET, min(5 * interval_of(set_up), 1.0))


# -- sessions and streams -------------------------------------------------------------------------


async def set_up_reading(
    ctx: Context, access: AccessNode | None = None, mode: str = "read"
) -> tuple[ControlProbe, StreamProbe, StreamSetUp]:
    """A session with a stream access set up for reading on a socket of the case's."""
    control = await ctx.session()
    probe = await open_stream(ctx, control)
    set_up = await probe.setup(control, access or readable_stream(ctx), mode)
    return control, probe, set_up


async def set_up_writing(
    ctx: Context, access: AccessNode, mode: str
) -> tuple[ControlProbe, StreamProbe, StreamSetUp]:
    """A session holding the privilege of `access` (R-RCTP-34), set up with mode `mode` (write
    or both) on a socket of the case's."""
    control = await ctx.session()
    await _acquire(ctx, control, access.path)
    probe = await open_stream(ctx, control)
    return control, probe, await probe.setup(control, access, mode)


async def short_write_timeout(probe: StreamProbe, set_up: StreamSetUp) -> float:
    """The stream's write timeout in seconds: its own, or shortened by set-timeout (D-RCTP-22)
    when that is over 1 s, so that a case that waits it out is quick; inconclusive when the
    server will not shorten it."""
    assert set_up.write_interval is not None
    if set_up.write_timeout <= 1.0:
        return set_up.write_timeout
    wanted = max(2 * set_up.micros(set_up.write_interval), 300_000)
    answer = await probe.ask(lambda i: TimeoutSet(i, Direction.WRITE, wanted), set_up.stream)
    if not isinstance(answer, TimeoutSetAck) or answer.timeout > 1_500_000:
        raise Inconclusive(
            f"writeTimeout {set_up.write_timeout:g} s could not be shortened: {flow_text(answer)}"
        )
    return answer.timeout / 1e6


async def stream_request(
    ctx: Context, control: ControlProbe, method: str, set_up: StreamSetUp
) -> None:
    """GO, PAUSE or STOP of the set-up stream, answered 200 (the rctp/state cases check them).
    A GO of a stream slower than `SLOWEST` makes the case not applicable: its DATA would not
    come often enough for the case's time."""
    if method == "GO" and set_up.mode != "write" and interval_of(set_up) > SLOWEST:
        raise NotApplicable(
            f"{set_up.access.path}'s readInterval {interval_of(set_up):g} s is longer than the"
            f" {SLOWEST:g} s this case has time for"
        )
    answer = await control.request(method, set_up.target)
    if answer.status != 200:
        raise Inconclusive(f"{method} {set_up.target} was answered {answer.status} {answer.reason}")


async def first_data(
    ctx: Context, probe: StreamProbe, set_up: StreamSetUp, requirement: str = "R-RCTP-44"
) -> tuple[Datagram, DataPayload]:
    """The next DATA of the stream after GO; none within the answer wait fails R-RCTP-44 (or
    `requirement`)."""
    found = await probe.data(set_up.stream)
    if found is None:
        raise Failed(
            requirement,
            f"DATA of stream {set_up.stream} every {interval_of(set_up):g} s after GO",
            f"none within {probe.wait:g} s",
        )
    return found


def decode_data(codec: ValuesCodec[DataNode], payload: DataPayload) -> dict[str, Value]:
    """The values of a DATA payload of the target's; one that does not decode fails R-RCTP-40."""
    try:
        return codec.decode(payload.body)
    except ProtocolError as error:
        raise Failed(
            "R-RCTP-40",
            f"DATA holding the values of {list(codec.names)} and nothing else",
            f"{error.reason} at byte {error.offset} of a DATA body of stream {payload.stream}",
        ) from None


def heartbeat_request(request_id: int) -> HeartbeatRequest:
    return HeartbeatRequest(request_id, ntp_from_unix(time.time()))


async def _acquire(ctx: Context, control: ControlProbe, path: str) -> None:
    """ACQUIRE the path; a 471 is another case's session not yet gone: asked again for a
    second, then inconclusive (the rctp/priv cases check ACQUIRE)."""
    loop = asyncio.get_running_loop()
    deadline = loop.time() + ctx.scale
    target = format_target(path)
    while True:
        answer = await control.request("ACQUIRE", target)
        if answer.status == 200:
            return
        if answer.status != 471 or loop.time() > deadline:
            raise Inconclusive(f"ACQUIRE {target} was answered {answer.status} {answer.reason}")
        await asyncio.sleep(0.05)


async def release_stream(control: ControlProbe, set_up: StreamSetUp) -> None:
    """STOP the stream and RELEASE everything, answers unchecked: the privilege is the whole
    server's, and the next case should find it free."""
    with contextlib.suppress(Failed):
        await control.request("STOP", set_up.target)
        await control.request("RELEASE", "*")


async def only_heartbeat_answered(
    ctx: Context, probe: StreamProbe, payloads: list[Payload], wanted: int, what: str
) -> None:
    """`payloads` and then a heartbeat request `wanted`, in one packet: the heartbeat is answered,
    and nothing else is (`what` names the payloads)."""
    got = await probe.answer_to(
        lambda: probe.send_packet([*payloads, FlowPayload(0, heartbeat_request(wanted))]), wanted
    )
    ctx.expect(got is not None, f"the heartbeat after {what} answered", "no answer")
    await probe.packets(QUIET)
    others = [f for d in probe.history for f in answers(d) if f.request_id != wanted]
    ctx.expect(not others, f"no answer to {what}", flow_text(others[0] if others else None))


def expect_nack(
    ctx: Context, answer: FlowMessage, operation: int, reason: NackReason, requirement: str
) -> None:
    """The answer is a NACK of `operation` with `reason`."""
    ctx.expect(
        isinstance(answer, Nack) and answer.operation == operation and answer.reason is reason,
        f"NACK {reason.value} ({reason.name.lower().replace('_', ' ')}) of operation {operation}",
        flow_text(answer),
        requirement,
    )


# -- pace -----------------------------------------------------------------------------------------


def once_per_interval(
    ctx: Context, count: int, window: float, interval: float, note: str = ""
) -> None:
    """R-RCTP-44: `count` DATA payloads in `window` seconds came once per `interval`, within
    D-RCTP-33's bounds for a server (read off the harness's clock: a timing check)."""
    expected = window / interval
    low, high = math.floor(0.75 * expected) - 1, math.ceil(1.2 * expected) + 1
    ctx.expect(
        low <= count <= high,
        f"about {expected:.0f} DATA in {window:g} s{note} ({low} to {high})",
        f"{count}",
        "R-RCTP-44",
        timing=True,
        by=outside_bounds(count, low, high) * interval,
    )
