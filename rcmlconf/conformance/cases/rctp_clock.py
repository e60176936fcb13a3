"""rctp/clock: the robot's clock as the data stream carries it — a heartbeat's ACK echoing T1 with
T2 <= T3 in NTP format, the path's delay left in the round trip, and DATA packets stamped with
that clock when they were sent (specs/rctp-2.0.md §6 D-RCTP-19, D-RCTP-22, R-RCTP-39, R-RCTP-48).
"""

from __future__ import annotations

import asyncio
import time

from rcmlconf.conformance.context import Context
from rcmlconf.conformance.probes.datagrams import ANSWER_TRIES
from rcmlconf.conformance.probes.stream import REPEAT, StreamProbe, flow_text
from rcmlconf.conformance.probes.stream_access import (
    first_data,
    heartbeat_request,
    set_up_reading,
    stream_request,
)
from rcmlconf.conformance.registry import case
from rcmlconf.conformance.verdicts import Failed
from rcmlconf.rctp.datastream import ClockSample, HeartbeatAck, ntp_difference, ntp_from_unix

#: |θ| beyond this is no clock but a format mistake: a Unix time in NTP's seconds reads as about
#: 2090 (θ ≈ +66 years), a clock at 1970 as θ ≈ -56 years (R-RCTP-48).
CLOCK_SPAN = 50 * 365.25 * 86400


async def _clock(ctx: Context, probe: StreamProbe) -> tuple[HeartbeatAck, ClockSample]:
    """A heartbeat's ACK, which must echo T1 and carry T2 <= T3 (R-RCTP-48), and its sample."""
    unix = time.time() - asyncio.get_running_loop().time()
    # Under an impairment, again until answered: each time a new request, so that the round
    # trip is measured from the T1 of the one answered.
    for _ in range(ANSWER_TRIES if probe.impairment is not None else 1):
        request = heartbeat_request(probe.next_request_id())
        probe.send_flow(request)
        got = await probe.answer(request.request_id, REPEAT if probe.impairment else None)
        if got is not None:
            break
    if got is None:
        raise Failed("R-RCTP-46", f"an ACK of heartbeat {request.request_id}", "none")
    datagram, ack = got
    t4 = ntp_from_unix(unix + datagram.at)
    if not isinstance(ack, HeartbeatAck):
        raise Failed("R-RCTP-48", "a heartbeat ACK", flow_text(ack))
    ctx.expect(ack.t1 == request.t1, f"T1 {request.t1} echoed", f"T1 {ack.t1}", "R-RCTP-48")
    held = ntp_difference(ack.t3, ack.t2)
    ctx.expect(held >= 0, "T2 (arrival) <= T3 (ACK sent)", f"T3 - T2 = {held:.6f} s", "R-RCTP-48")
    return ack, ClockSample.from_times(request.t1, ack.t2, ack.t3, t4)


def _precision(ctx: Context) -> float:
    """The robot's timePrecision, and a millisecond for the harness's own clock."""
    return (ctx.robot.time_precision or 0.0) + 0.001


@case(
    "rctp/clock/heartbeat",
    "A heartbeat's ACK echoes T1 and carries T2 <= T3 in NTP format, within the round trip",
    ["R-RCTP-48"],
)
async def heartbeat(ctx: Context) -> None:
    _, probe, _ = await set_up_reading(ctx)
    _, sample = await _clock(ctx, probe)
    ctx.expect(
        sample.delay >= -_precision(ctx),
        "T3 - T2 no longer than the round trip T4 - T1",
        f"δ = {sample.delay:.6f} s",
    )
    ctx.expect(
        abs(sample.offset) < CLOCK_SPAN,
        "T2 and T3 in NTP format (seconds since 1900)",
        f"an offset of {sample.offset / 86400 / 365.25:.1f} years from the harness's clock",
    )


@case(
    "rctp/clock/heartbeat-delay",
    "Through 40 ms of delay each way, T2 and T3 leave the delay in the round trip δ",
    ["R-RCTP-48"],
    impairment="delay=40ms",
)
async def heartbeat_delay(ctx: Context) -> None:
    _, probe, _ = await set_up_reading(ctx)
    ack, sample = await _clock(ctx, probe)
    impairment = probe.impairment
    assert impairment is not None
    least = 2 * (impairment.delay - impairment.jitter) - 2 * _precision(ctx) - 0.005
    ctx.expect(
        sample.delay >= least,
        f"δ of at least {least:.3f} s (the path's delay): T2 when the request arrived, T3 when"
        " the ACK left",
        f"δ = {sample.delay:.6f} s, T3 - T2 = {ntp_difference(ack.t3, ack.t2):.6f} s",
    )


@case(
    "rctp/clock/packet-timestamp",
    "DATA packets carry the robot's clock (that of its heartbeat ACK) when they were sent",
    ["R-RCTP-39"],
)
async def packet_timestamp(ctx: Context) -> None:
    control, probe, set_up = await set_up_reading(ctx)
    _, sample = await _clock(ctx, probe)
    loop = asyncio.get_running_loop()
    unix = time.time() - loop.time()
    await stream_request(ctx, control, "GO", set_up)
    slack = max(sample.delay, 0.0) / 2 + _precision(ctx)
    for _ in range(5):
        datagram, _ = await first_data(ctx, probe, set_up)
        assert datagram.packet is not None
        # By the harness's clock, then moved to the robot's by the heartbeat's offset θ.
        age = ntp_difference(ntp_from_unix(unix + datagram.at), datagram.packet.timestamp)
        ctx.expect(
            abs(age) < CLOCK_SPAN,
            "a timestamp in NTP format (seconds since 1900)",
            f"{age / 86400 / 365.25:+.1f} years from the harness's clock",
        )
        age += sample.offset
        ctx.expect(
            -slack - 0.005 <= age <= 0.25 + slack,
            "a timestamp of the robot's clock at most 0.25 s before the packet arrived",
            f"stamped {age:+.3f} s before it arrived, by the robot's clock",
        )
