"""rctp/flow: the FLOW requests of the data stream and their answers — get and set the interval
and the timeout, the NACKs of a value refused, an unknown stream or operation, a request the
server does not own or that is malformed, broken bodies ignored, and every request answered once,
repeated as given, through duplicates, late packets and reordering (specs/rctp-2.0.md §6
D-RCTP-22, D-RCTP-24, R-RCTP-44, R-RCTP-46, R-RCTP-47, R-RCTP-52, R-RCTP-53).

Each case opens its own session and data-stream socket (`probes.stream`);
rctp/flow/timeout-too-short holds the access privilege to set up for writing, so it runs alone
(`serial`).
"""

from __future__ import annotations

import asyncio
from collections.abc import Callable
from functools import partial

from rcmlconf.conformance.context import Context
from rcmlconf.conformance.probes.stream import answers, flow_text
from rcmlconf.conformance.probes.stream_access import (
    MODULO,
    QUIET,
    UNKNOWN_OPERATION,
    expect_nack,
    first_data,
    heartbeat_request,
    once_per_interval,
    only_heartbeat_answered,
    release_stream,
    set_up_reading,
    set_up_writing,
    stream_request,
    writable_stream,
)
from rcmlconf.conformance.registry import case
from rcmlconf.conformance.verdicts import Failed, Inconclusive
from rcmlconf.rctp.datastream import (
    DataPayload,
    Direction,
    FlowMessage,
    HeartbeatAck,
    HeartbeatRequest,
    IntervalGet,
    IntervalGetAck,
    IntervalSet,
    IntervalSetAck,
    NackReason,
    Operation,
    Payload,
    TimeoutSet,
    TimeoutSetAck,
    UnknownRequest,
    encode_flow,
)
from rcmlconf.rctp.datastream.endpoint import micros
from rcmlconf.rctp.datastream.packets import MalformedFlowPayload


def _setter(direction: Direction, interval: int) -> Callable[[int], FlowMessage]:
    """A set-interval request of `interval` microseconds, given its id."""
    return lambda request_id: IntervalSet(request_id, direction, interval)


@case(
    "rctp/flow/get-interval",
    "A get-interval request is answered ACK with the read direction and the RCML's readInterval",
    ["R-RCTP-46"],
)
async def get_interval(ctx: Context) -> None:
    _, probe, set_up = await set_up_reading(ctx)
    answer = await probe.ask(lambda i: IntervalGet(i, Direction.READ), set_up.stream)
    expected = set_up.micros(set_up.read_interval)
    ctx.expect(
        answer == IntervalGetAck(answer.request_id, Direction.READ, expected),
        f"ACK: direction read, interval {expected} us (D-RCTP-18)",
        flow_text(answer),
    )


@case(
    "rctp/flow/set-interval",
    "A set-interval request above the RCML's is ACKed and the server then sends at that interval",
    ["R-RCTP-46", "R-RCTP-44"],
)
async def set_interval(ctx: Context) -> None:
    control, probe, set_up = await set_up_reading(ctx)
    shortest = set_up.micros(set_up.read_interval)
    wanted = 3 * shortest
    answer = await probe.ask(lambda i: IntervalSet(i, Direction.READ, wanted), set_up.stream)
    if not isinstance(answer, IntervalSetAck):
        raise Failed("R-RCTP-46", f"ACK of interval {wanted} us", flow_text(answer))
    ctx.expect(
        answer.direction is Direction.READ and answer.interval >= shortest,
        f"direction read, an interval in force of at least {shortest} us",
        flow_text(answer),
    )
    interval = answer.interval / 1e6
    window = min(2.0, max(0.5, 8 * interval))
    await stream_request(ctx, control, "GO", set_up)
    await first_data(ctx, probe, set_up)
    count = sum(
        1
        for d in await probe.packets(window)
        if d.packet and any(isinstance(p, DataPayload) for p in d.packet.payloads)
    )
    once_per_interval(ctx, count, window, interval, " at the interval ACKed")


@case(
    "rctp/flow/interval-too-short",
    "A read interval shorter than the RCML's is refused NACK 3; the RCML's own is ACKed",
    ["R-RCTP-47"],
)
async def interval_too_short(ctx: Context) -> None:
    _, probe, set_up = await set_up_reading(ctx)
    shortest = set_up.micros(set_up.read_interval)
    for interval in (shortest - 1, shortest // 2):
        answer = await probe.ask(_setter(Direction.READ, interval), set_up.stream)
        expect_nack(ctx, answer, Operation.SET_INTERVAL, NackReason.VALUE_REFUSED, "R-RCTP-47")
    answer = await probe.ask(lambda i: IntervalSet(i, Direction.READ, shortest), set_up.stream)
    ctx.expect(
        isinstance(answer, IntervalSetAck), f"ACK of {shortest} us (the RCML's)", flow_text(answer)
    )


@case(
    "rctp/flow/repeated-id",
    "A request with an id already answered gets the answer already given, and changes nothing",
    ["R-RCTP-46"],
)
async def repeated_id(ctx: Context) -> None:
    _, probe, set_up = await set_up_reading(ctx)
    shortest = set_up.micros(set_up.read_interval)
    request_id = probe.next_request_id()
    answered: list[FlowMessage] = []
    for interval in (3 * shortest, 4 * shortest):
        request = IntervalSet(request_id, Direction.READ, interval)
        got = await probe.answer_to(partial(probe.send_flow, request, set_up.stream), request_id)
        if got is None:
            raise Failed("R-RCTP-46", f"an answer to request {request_id}", "none")
        answered.append(got[1])
    first, second = answered
    ctx.expect(second == first, f"{flow_text(first)} again", flow_text(second))
    now = await probe.ask(lambda i: IntervalGet(i, Direction.READ), set_up.stream)
    if isinstance(first, IntervalSetAck):
        ctx.expect(
            isinstance(now, IntervalGetAck) and now.interval == first.interval,
            f"the interval still {first.interval} us",
            flow_text(now),
        )


@case(
    "rctp/flow/unknown-stream",
    "A request about a stream not set up, or a direction its mode does not carry, is NACK 2",
    ["R-RCTP-46"],
)
async def unknown_stream(ctx: Context) -> None:
    _, probe, set_up = await set_up_reading(ctx)
    other = 255 if set_up.stream != 255 else 254
    answer = await probe.ask(lambda i: IntervalGet(i, Direction.READ), other)
    expect_nack(ctx, answer, Operation.GET_INTERVAL, NackReason.UNKNOWN_STREAM, "R-RCTP-46")
    answer = await probe.ask(lambda i: IntervalGet(i, Direction.WRITE), set_up.stream)
    expect_nack(ctx, answer, Operation.GET_INTERVAL, NackReason.UNKNOWN_STREAM, "R-RCTP-46")


@case(
    "rctp/flow/not-owner",
    "Setting the read timeout, which the client owns as the receiver, at the server is NACK 4",
    ["R-RCTP-46"],
)
async def not_owner(ctx: Context) -> None:
    _, probe, set_up = await set_up_reading(ctx)
    timeout = max(micros(set_up.read_timeout), 4 * set_up.micros(set_up.read_interval))
    answer = await probe.ask(lambda i: TimeoutSet(i, Direction.READ, timeout), set_up.stream)
    expect_nack(ctx, answer, Operation.SET_TIMEOUT, NackReason.NOT_PERMITTED, "R-RCTP-46")


@case(
    "rctp/flow/not-owner-write-interval",
    "Setting the write interval, which the client owns as the sender, at the server is NACK 4",
    ["R-RCTP-46"],
    serial=True,
)
async def not_owner_write_interval(ctx: Context) -> None:
    control, probe, set_up = await set_up_writing(ctx, writable_stream(ctx), "write")
    # Longer than the RCML's, so that only the owner's rule can refuse it (not R-RCTP-47's).
    interval = 2 * set_up.micros(set_up.write_interval)
    answer = await probe.ask(lambda i: IntervalSet(i, Direction.WRITE, interval), set_up.stream)
    expect_nack(ctx, answer, Operation.SET_INTERVAL, NackReason.NOT_PERMITTED, "R-RCTP-46")
    await release_stream(control, set_up)


@case(
    "rctp/flow/unknown-operation",
    "A FLOW request for an operation the server does not know is answered NACK 1, echoing it",
    ["R-RCTP-53"],
)
async def unknown_operation(ctx: Context) -> None:
    _, probe, set_up = await set_up_reading(ctx)
    answer = await probe.ask(
        lambda i: UnknownRequest(i, UNKNOWN_OPERATION, b"\x01\x02\x03"),
        set_up.stream,
        requirement="R-RCTP-53",
    )
    expect_nack(ctx, answer, UNKNOWN_OPERATION, NackReason.UNKNOWN_OPERATION, "R-RCTP-53")


@case(
    "rctp/flow/malformed-request",
    "FLOW requests whose fields do not fit their operation are answered NACK 5",
    ["R-RCTP-53", "R-RCTP-52"],
)
async def malformed_request(ctx: Context) -> None:
    _, probe, set_up = await set_up_reading(ctx)
    stream = set_up.stream

    def get(request_id: int) -> bytes:
        return encode_flow(IntervalGet(request_id, Direction.READ))

    bodies: list[tuple[int, Operation, Callable[[int], bytes]]] = [
        (stream, Operation.GET_INTERVAL, lambda i: get(i) + b"\x00"),  # a byte too many
        (stream, Operation.GET_INTERVAL, lambda i: get(i)[:-1] + b"\x07"),  # direction 7
        (0, Operation.HEARTBEAT, lambda i: encode_flow(heartbeat_request(i))[:8]),  # T1 cut short
    ]
    for on, operation, body in bodies:
        request_id = probe.next_request_id()
        broken = MalformedFlowPayload(on, body(request_id), "sent broken", 0)
        got = await probe.answer_to(partial(probe.send_packet, [broken]), request_id)
        if got is None:
            raise Failed("R-RCTP-53", f"NACK 5 of request {request_id}", "no answer")
        expect_nack(ctx, got[1], operation, NackReason.MALFORMED, "R-RCTP-53")


@case(
    "rctp/flow/broken-body-ignored",
    "Broken FLOW bodies that are no readable request are ignored, the packet's others handled",
    ["R-RCTP-53"],
)
async def broken_body_ignored(ctx: Context) -> None:
    _, probe, _ = await set_up_reading(ctx)
    wanted = probe.next_request_id()
    broken = [
        b"\x00\x01",  # a request shorter than its preamble
        bytes([1, UNKNOWN_OPERATION]) + (wanted ^ 0x8000).to_bytes(2, "big"),  # ACK of nothing
        bytes([2, Operation.HEARTBEAT]) + (wanted ^ 0x4000).to_bytes(2, "big") + b"\x09",
    ]
    payloads: list[Payload] = [MalformedFlowPayload(0, body, "sent broken", 0) for body in broken]
    await only_heartbeat_answered(ctx, probe, payloads, wanted, "the broken bodies")


@case(
    "rctp/flow/stale-packet-answered",
    "FLOW requests in a duplicate or late packet are answered all the same",
    ["R-RCTP-46"],
)
async def stale_packet_answered(ctx: Context) -> None:
    _, probe, _ = await set_up_reading(ctx)
    answer = await probe.ask(heartbeat_request)
    ctx.expect(isinstance(answer, HeartbeatAck), "ACK of a heartbeat", flow_text(answer))
    newest = probe.last_sequence
    for sequence, what in ((newest, "duplicate"), ((newest - 1) % MODULO, "late")):
        request_id = probe.next_request_id()
        heartbeat = heartbeat_request(request_id)
        got = await probe.answer_to(
            partial(probe.send_flow, heartbeat, sequence=sequence), request_id
        )
        ctx.expect(
            got is not None and isinstance(got[1], HeartbeatAck),
            f"ACK of a heartbeat in a {what} packet ({sequence})",
            flow_text(got[1]) if got else "no answer",
        )


@case(
    "rctp/flow/reordered-duplicated",
    "Through reordering and duplication, every request is answered and a repeat as before",
    ["R-RCTP-46"],
    impairment="reorder=30%,gap=40ms,duplicate=30%",
)
async def reordered_duplicated(ctx: Context) -> None:
    _, probe, _ = await set_up_reading(ctx)
    sent: dict[int, HeartbeatRequest] = {}
    for _ in range(12):
        request = heartbeat_request(probe.next_request_id())
        sent[request.request_id] = request
        probe.send_flow(request)
        await asyncio.sleep(0.015)

    def answered() -> dict[int, list[FlowMessage]]:
        got: dict[int, list[FlowMessage]] = {}
        for datagram in probe.history:
            for flow in answers(datagram):
                got.setdefault(flow.request_id, []).append(flow)
        return got

    loop = asyncio.get_running_loop()
    deadline = loop.time() + probe.wait
    while set(answered()) < set(sent) and (left := deadline - loop.time()) > 0:
        await probe.packet(left)
    await probe.packets(QUIET)  # the copies of the last ones
    got = answered()
    outward, _ = probe.channels
    if outward is not None and not (outward.counts.reordered or outward.counts.duplicated):
        raise Inconclusive("the impairment neither reordered nor duplicated a request")
    for request_id, request in sent.items():
        found = got.get(request_id, [])
        ctx.expect(bool(found), f"an answer to request {request_id}", "none")
        ctx.expect(
            all(f == found[0] for f in found),
            f"one answer to request {request_id}, repeated as given",
            "; ".join(flow_text(f) for f in found),
        )
        ctx.expect(
            isinstance(found[0], HeartbeatAck) and found[0].t1 == request.t1,
            f"ACK of request {request_id} echoing T1",
            flow_text(found[0]),
        )


@case(
    "rctp/flow/timeout-too-short",
    "A write timeout shorter than twice the write interval is refused NACK 3; twice it is ACKed",
    ["R-RCTP-47"],
    serial=True,
)
async def timeout_too_short(ctx: Context) -> None:
    control, probe, set_up = await set_up_writing(ctx, writable_stream(ctx), "write")
    interval = set_up.micros(set_up.write_interval)
    too_short = 2 * interval - 1
    answer = await probe.ask(lambda i: TimeoutSet(i, Direction.WRITE, too_short), set_up.stream)
    expect_nack(ctx, answer, Operation.SET_TIMEOUT, NackReason.VALUE_REFUSED, "R-RCTP-47")
    enough = 2 * interval
    answer = await probe.ask(lambda i: TimeoutSet(i, Direction.WRITE, enough), set_up.stream)
    ctx.expect(
        isinstance(answer, TimeoutSetAck) and answer.timeout >= enough,
        f"ACK of a timeout of {enough} us (twice the interval)",
        flow_text(answer),
    )
    await release_stream(control, set_up)
