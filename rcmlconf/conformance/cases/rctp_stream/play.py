"""rctp/stream, what GO, PAUSE and STOP do to a stream's DATA: none before GO, DATA once per
readInterval while it plays, none past what was in flight after PAUSE or STOP, the sequence
numbers going on by one after GO again, and 455 for a GO after STOP (specs/rctp-2.0.md §6
D-RCTP-18, D-RCTP-21, R-RCTP-20, R-RCTP-41, R-RCTP-44).

Windows in which no DATA may come are short and fixed (`QUIET`, after `GRACE` for what was in
flight: `probes.stream_access`), so that a slow server may pass such a case wrongly, never fail it
wrongly.
"""

from __future__ import annotations

import asyncio

from rcmlconf.conformance.context import Context
from rcmlconf.conformance.probes.control import ControlProbe
from rcmlconf.conformance.probes.stream import StreamProbe, StreamSetUp
from rcmlconf.conformance.probes.stream_access import (
    GRACE,
    MEASURE,
    MODULO,
    first_data,
    has_data,
    interval_of,
    once_per_interval,
    quiet_for,
    set_up_reading,
    stream_request,
)
from rcmlconf.conformance.registry import case
from rcmlconf.rctp.datastream import DataPayload


async def _silenced(ctx: Context, method: str) -> tuple[ControlProbe, StreamProbe, StreamSetUp]:
    """A stream set up for reading, played, then `method` (PAUSE or STOP): past what was in
    flight, no DATA of it comes (R-RCTP-44)."""
    control, probe, set_up = await set_up_reading(ctx)
    await stream_request(ctx, control, "GO", set_up)
    await first_data(ctx, probe, set_up)
    await stream_request(ctx, control, method, set_up)
    await asyncio.sleep(GRACE)
    probe.drain()
    late = [d for d in await probe.packets(quiet_for(set_up)) if has_data(d, set_up)]
    ctx.expect(not late, f"no DATA after {method}", f"{len(late)} packets with DATA", "R-RCTP-44")
    return control, probe, set_up


@case(
    "rctp/stream/no-data-before-go",
    "A stream set up but not yet started sends no DATA; after GO it does",
    ["R-RCTP-44"],
)
async def no_data_before_go(ctx: Context) -> None:
    control, probe, set_up = await set_up_reading(ctx)
    early = await probe.packets(quiet_for(set_up))
    data = [d for d in early if has_data(d, set_up)]
    ctx.expect(not data, "no DATA before GO", f"{len(data)} packets with DATA")
    await stream_request(ctx, control, "GO", set_up)
    await first_data(ctx, probe, set_up)


@case(
    "rctp/stream/data-interval",
    "A playing stream's DATA comes once per readInterval, measured over up to a second",
    ["R-RCTP-44"],
)
async def data_interval(ctx: Context) -> None:
    control, probe, set_up = await set_up_reading(ctx)
    interval = interval_of(set_up)
    window = min(MEASURE, max(0.5, 10 * interval))
    await stream_request(ctx, control, "GO", set_up)
    await first_data(ctx, probe, set_up)
    count = 0
    for datagram in await probe.packets(window):
        assert datagram.packet is not None
        count += sum(
            1
            for p in datagram.packet.payloads
            if isinstance(p, DataPayload) and p.stream == set_up.stream
        )
    once_per_interval(ctx, count, window, interval)


@case(
    "rctp/stream/pause",
    "PAUSE stops a stream's DATA; GO again resumes it, the sequence numbers going on by one",
    ["R-RCTP-44", "R-RCTP-41"],
)
async def pause(ctx: Context) -> None:
    control, probe, set_up = await _silenced(ctx, "PAUSE")
    last = probe.history[-1].packet
    assert last is not None
    await stream_request(ctx, control, "GO", set_up)
    datagram, _ = await first_data(ctx, probe, set_up)
    assert datagram.packet is not None
    expected = (last.sequence + 1) % MODULO
    ctx.expect(
        datagram.packet.sequence == expected,
        f"sequence {expected} after {last.sequence}",
        f"{datagram.packet.sequence}",
        "R-RCTP-41",
    )


@case(
    "rctp/stream/stop",
    "STOP ends a stream's DATA, and GO of it is then 455 until it is set up again",
    ["R-RCTP-44", "R-RCTP-20"],
)
async def stop(ctx: Context) -> None:
    control, _, set_up = await _silenced(ctx, "STOP")
    ctx.expect_status(await control.request("GO", set_up.target), 455, "R-RCTP-20")
