"""rctp/stream, the packets of DATA a server sends: from the server_port it named, in D-RCTP-19's
layout, numbered one more each from a random start (the gaps under loss exactly the packets lost),
each DATA payload holding exactly the readable nodes' values (specs/rctp-2.0.md §6 D-RCTP-19,
D-RCTP-20, D-RCTP-21, R-RCTP-39 to R-RCTP-41, R-RCTP-56).
"""

from __future__ import annotations

import asyncio
import itertools

from rcmlconf.conformance.context import Context
from rcmlconf.conformance.probes.stream import open_stream
from rcmlconf.conformance.probes.stream_access import (
    MEASURE,
    MODULO,
    decode_data,
    first_data,
    interval_of,
    readable_stream,
    set_up_reading,
    stream_request,
)
from rcmlconf.conformance.registry import case
from rcmlconf.conformance.verdicts import Inconclusive
from rcmlconf.rctp.datastream import Direction, FlowPayload, stream_codec


@case(
    "rctp/stream/data-from-server-port",
    "After GO, DATA comes from the server_port of SETUP's answer to the client_port asked",
    ["R-RCTP-56"],
)
async def data_from_server_port(ctx: Context) -> None:
    control, probe, set_up = await set_up_reading(ctx)
    await stream_request(ctx, control, "GO", set_up)
    for _ in range(3):  # `packet` checks the source of each (strict)
        await first_data(ctx, probe, set_up, "R-RCTP-56")


@case(
    "rctp/stream/packet-layout",
    "The server's packets have D-RCTP-19's layout: version 2, the session's tag, payloads filling"
    " the datagram",
    ["R-RCTP-39"],
)
async def packet_layout(ctx: Context) -> None:
    control, probe, set_up = await set_up_reading(ctx)
    await stream_request(ctx, control, "GO", set_up)
    for _ in range(10):  # `packet` decodes each and checks its tag (strict)
        await first_data(ctx, probe, set_up)
    for datagram in probe.history:
        assert datagram.packet is not None
        for one in datagram.packet.payloads:
            stream = getattr(one, "stream", 0)
            ctx.expect(
                isinstance(one, FlowPayload) or stream == set_up.stream,
                f"payloads of stream {set_up.stream} (the one set up) or FLOW",
                f"{type(one).__name__} of stream {stream}",
            )


@case(
    "rctp/stream/consecutive-sequence",
    "The server numbers its packets one more each, modulo 65,536",
    ["R-RCTP-41"],
)
async def consecutive_sequence(ctx: Context) -> None:
    control, probe, set_up = await set_up_reading(ctx)
    await stream_request(ctx, control, "GO", set_up)
    for _ in range(20):
        await first_data(ctx, probe, set_up)
    got = [d for d in probe.history if d.packet is not None]
    impairment = ctx.impairment  # --impair's or none: this case declares none of its own
    for earlier, later in itertools.pairwise(got):
        assert earlier.packet is not None
        assert later.packet is not None
        before, after = earlier.packet.sequence, later.packet.sequence
        step = (after - before) % MODULO
        if step == 1:
            continue
        if not impairment.is_none:
            if step == 0 or step >= MODULO // 2:
                continue  # a duplicate, or a late packet: the impairment's doing
            if step <= 1 + later.lost_before:
                continue  # the numbers of the datagrams the impairment lost in between
            if impairment.reorder:
                raise Inconclusive(f"{after} after {before}: a packet held back by reordering?")
        ctx.expect(False, f"{(before + 1) % MODULO} after {before}", f"{after} after {before}")


@case(
    "rctp/stream/data-values",
    "Each DATA payload holds exactly the readable nodes' values, in canonical order and range",
    ["R-RCTP-40"],
)
async def data_values(ctx: Context) -> None:
    control, probe, set_up = await set_up_reading(ctx)
    codec = stream_codec(set_up.access, Direction.READ)
    await stream_request(ctx, control, "GO", set_up)
    for _ in range(5):
        _, payload = await first_data(ctx, probe, set_up)
        values = decode_data(codec, payload)
        for node in codec.nodes:
            problem = node.out_of_range(values[node.name])
            ctx.expect(problem is None, f"{node.path} within its range", str(problem))


@case(
    "rctp/stream/random-start",
    "Three sessions' data streams do not all start their sequence numbers at the same value",
    ["R-RCTP-41"],
)
async def random_start(ctx: Context) -> None:
    access = readable_stream(ctx)

    async def start(flow: int) -> int:
        control = await ctx.session()
        probe = await open_stream(ctx, control, flow)
        set_up = await probe.setup(control, access)
        await stream_request(ctx, control, "GO", set_up)
        datagram, _ = await first_data(ctx, probe, set_up)
        assert datagram.packet is not None
        return datagram.packet.sequence

    starts = await asyncio.gather(*(start(flow) for flow in range(3)))
    ctx.expect(
        len(set(starts)) > 1,
        "sequence numbers starting at random values",
        f"every session starting at {starts[0]}",
    )


@case(
    "rctp/stream/sequence-under-loss",
    "Through 20% loss, every gap in the server's sequence numbers is exactly the packets lost",
    ["R-RCTP-41"],
    impairment="loss=20%",
)
async def sequence_under_loss(ctx: Context) -> None:
    control, probe, set_up = await set_up_reading(ctx)
    await stream_request(ctx, control, "GO", set_up)
    window = min(MEASURE, max(0.4, 30 * interval_of(set_up)))
    got = [d for d in await probe.packets(window) if d.packet is not None]
    if len(got) < 2:
        raise Inconclusive(f"{len(got)} packets got through the impairment in {window:g} s")
    for before, after in itertools.pairwise(got):
        assert before.packet is not None
        assert after.packet is not None
        step = (after.packet.sequence - before.packet.sequence) % MODULO
        ctx.expect(
            step == 1 + after.lost_before,
            f"{(before.packet.sequence + 1 + after.lost_before) % MODULO} after"
            f" {before.packet.sequence} ({after.lost_before} lost between)",
            f"{after.packet.sequence}",
        )
