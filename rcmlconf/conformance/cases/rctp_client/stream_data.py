"""rctp/client, what the client under test does with the played robot's DATA (D-RCTP-31 step 6):
it takes well-formed DATA and echoes it, and never takes DATA that is stale, out of range or in a
packet that is not the session's (R-RCTP-40, R-RCTP-42, R-RCTP-43, R-RCTP-58; specs/rctp-2.0.md
D-RCTP-20, D-RCTP-21); broken FLOW bodies beside DATA it ignores, and takes the DATA (R-RCTP-53,
D-RCTP-22)."""

from __future__ import annotations

import asyncio
import random
from collections.abc import Callable

from rcmlconf.conformance.cases.rctp_client.scenario import scenario_case
from rcmlconf.conformance.cases.rctp_client.streams import (
    shared_nodes,
    shown,
    until_playing,
    visible,
    written,
)
from rcmlconf.conformance.context import Context
from rcmlconf.conformance.probes.played import PlayedServer
from rcmlconf.conformance.probes.played_stream import STREAM_ID, PlayedStream
from rcmlconf.conformance.probes.stream import StreamProbe
from rcmlconf.conformance.probes.stream_access import UNKNOWN_TYPE
from rcmlconf.conformance.verdicts import Inconclusive
from rcmlconf.rcml.model import AccessNode, DataNode
from rcmlconf.rctp.bodies import ValuesCodec
from rcmlconf.rctp.datastream import (
    DataPayload,
    Direction,
    FlowPayload,
    HeartbeatAck,
    HeartbeatRequest,
    Message,
    Nack,
    NackReason,
    Operation,
    Payload,
    UnknownPayload,
    encode_flow,
    stream_codec,
)
from rcmlconf.rctp.datastream.packets import MalformedFlowPayload
from rcmlconf.rctp.targets import format_target
from rcmlconf.values import Kind, Value
from rcmlconf.wording import plural

#: How long the client's DATA is watched after it answered a server BYE or STOP: ten write
#: intervals of the harness's robot.
WATCH = 0.5
#: How far ahead of the newest the stale packet of stream-stale-not-taken is numbered: over
#: half the numbers, so behind it (D-RCTP-21).
FAR = 40000


@scenario_case(
    "rctp/client/stream-echo",
    "The played robot's DATA is taken: the client's DATA carries the values it got, in canonical"
    " order (the harness's robot declares them in another)",
    ["R-RCTP-58", "R-RCTP-40"],
)
async def stream_echo(ctx: Context) -> None:
    server, stream, access = await until_playing(ctx)
    shared = shared_nodes(access)
    for node in access.readable():
        server.values[node.path] = visible(node)
    await server.reach("PAUSE")
    echoed = written(stream, access)
    wanted = {n.name: server.values[n.path] for n in shared}
    ctx.expect(
        any(all(v.get(k) == x for k, x in wanted.items()) for v in echoed),
        f"DATA with {shown(shared, wanted)} (the played robot's, D-RCTP-31 step 6), both ways"
        " in canonical order",
        shown(shared, echoed[-1]) if echoed else "no DATA",
        "R-RCTP-58",
    )
    await server.reach("BYE")


@scenario_case(
    "rctp/client/stream-stale-not-taken",
    "DATA in a packet that is not newer than one already taken (older, the same number again, or"
    f" {FAR} ahead, which is {0x10000 - FAR} behind) is not taken: an older value never replaces"
    " a newer one",
    ["R-RCTP-43"],
)
async def stream_stale_not_taken(ctx: Context) -> None:
    # D-RCTP-21 compares numbers as serial numbers (RFC 1982): a client comparing them as plain
    # integers takes the packet FAR ahead, which it must not, when every number the played
    # server sent is below it. A start (random, D-RCTP-19) low enough leaves room for that.
    start = random.Random(ctx.impairment_seed("start")).randrange(1, 0x10000 - FAR - 1000)
    server, stream, access, codec, newer = await _hushed(ctx, start)
    marks = _marks(ctx, access, 3)
    sequence = stream.probe.last_sequence  # the newer packet's
    sent = [
        (sequence, {**newer, **marks[0]}, "the packet with its number again"),
        ((sequence - 1) & 0xFFFF, {**newer, **marks[1]}, "the older packet"),
        ((sequence + FAR) & 0xFFFF, {**newer, **marks[2]}, f"the packet {FAR} ahead"),
    ]
    for number, values, _ in sent:
        stream.probe.send_packet([DataPayload(STREAM_ID, codec.encode(values))], sequence=number)
    await _judge_echo(ctx, server, stream, access, newer, [(v, what) for _, v, what in sent])


@scenario_case(
    "rctp/client/stream-out-of-range-not-taken",
    "DATA holding a value outside its node's range is not taken, not even its other values",
    ["R-RCTP-58"],
)
async def stream_out_of_range(ctx: Context) -> None:
    server, stream, access, codec, newer = await _hushed(ctx)
    ranged = [n for n in shared_nodes(access) if n.maximum is not None]
    if not ranged:
        raise Inconclusive(f"{access.path} has no node with a max that it reads and writes")
    node = ranged[0]
    assert node.maximum is not None
    over = node.maximum * 2 + 1
    # The other nodes' values differ from those taken: a client that applies the values within
    # range and skips the one outside (not together, R-RCTP-58) shows them.
    mark = _marks(ctx, access, 1)[0]
    if node.name in mark:
        ctx.cannot_check(f"values applied together: {node.name} is the only node to mark")
    beyond = {**newer, **mark, node.name: over}
    for _ in range(3):
        stream.probe.send_packet([DataPayload(STREAM_ID, codec.encode(beyond))])
    outside = f"those with {node.name}={over:g}, outside {node.minimum} to {node.maximum}"
    await _judge_echo(ctx, server, stream, access, newer, [(beyond, outside)])


@scenario_case(
    "rctp/client/stream-foreign-packets-dropped",
    "Packets of another version, with another tag or from another port are dropped unanswered:"
    " their DATA is never taken, their heartbeats never answered",
    ["R-RCTP-42"],
)
async def stream_foreign_packets_dropped(ctx: Context) -> None:
    hushed = await _hushed(ctx)
    probe = hushed[1].probe
    set_up = probe.set_up
    assert set_up is not None
    other = await StreamProbe.open(probe.local[0], ctx.transcript, probe.wait)
    ctx.on_close(other.close)

    await _dropped(
        ctx,
        hushed,
        {
            "of version 3": lambda p: probe.send(b"\x03" + probe.packet_bytes(p)[1:]),
            "of another tag": lambda p: probe.send_packet(p, tag=set_up.tag ^ 0x5A5A5A5A),
            "of another port": lambda p: other.send_packet(p, tag=set_up.tag, to=set_up.server),
        },
        other,
    )


@scenario_case(
    "rctp/client/stream-broken-framing-dropped",
    "Packets whose framing is broken (a payload count above their payloads, stray bytes after"
    " them) are dropped whole: their DATA is never taken, their heartbeats never answered",
    ["R-RCTP-42"],
)
async def stream_broken_framing_dropped(ctx: Context) -> None:
    hushed = await _hushed(ctx)
    probe = hushed[1].probe
    # The DATA and the heartbeat come first: a client that walks the payloads and finds the
    # framing broken only after them has already taken them.
    await _dropped(
        ctx,
        hushed,
        {
            "with a payload count one above its payloads": lambda p: probe.send(
                _count_one_up(probe.packet_bytes(p))
            ),
            "with 3 stray bytes after its payloads": lambda p: probe.send(
                probe.packet_bytes(p) + b"\x01\x01\x00"
            ),
        },
    )


def _count_one_up(data: bytes) -> bytes:
    """The packet with its payload count one above its payloads (D-RCTP-19)."""
    return data[:1] + bytes([data[1] + 1]) + data[2:]


#: Sends a packet of the payloads given, in a way the client must drop it (R-RCTP-42).
Sender = Callable[[list[Payload]], object]


async def _dropped(
    ctx: Context, hushed: Hushed, senders: dict[str, Sender], other: StreamProbe | None = None
) -> None:
    """After `_hushed`: for each way of `senders` (what is wrong with the packet, its sender), a
    packet of DATA of values of its own and a heartbeat, which the client must neither take nor
    answer (R-RCTP-42); `other`, a second probe of the case's, whose answers count too."""
    server, stream, access, codec, newer = hushed
    sent, asked = [], []
    for (kind, send), mark in zip(senders.items(), _marks(ctx, access, len(senders)), strict=True):
        values = {**newer, **mark}
        beat = HeartbeatRequest(stream.probe.next_request_id(), stream.robot_time())
        send([DataPayload(STREAM_ID, codec.encode(values)), FlowPayload(0, beat)])
        sent.append((values, f"the packet {kind}"))
        asked.append((beat.request_id, kind))
    await _judge_echo(ctx, server, stream, access, newer, sent)
    received = [*stream.received, *(other.drain() if other is not None else [])]
    answered = {
        p.flow.request_id
        for one in received
        if one.packet is not None
        for p in one.packet.payloads
        if isinstance(p, FlowPayload) and p.flow.message is not Message.REQUEST
    }
    wrongly = [kind for request_id, kind in asked if request_id in answered]
    ctx.expect(
        not wrongly,
        "no answer to the heartbeats of those packets",
        f"an answer to the heartbeat of the packet {', '.join(wrongly)}",
        "R-RCTP-42",
    )


@scenario_case(
    "rctp/client/stream-undecodable-not-taken",
    "DATA whose body is one byte too long or one byte short is not taken",
    ["R-RCTP-58"],
)
async def stream_undecodable_not_taken(ctx: Context) -> None:
    server, stream, access, codec, newer = await _hushed(ctx)
    long, short = ({**newer, **mark} for mark in _marks(ctx, access, 2))
    sent = [
        (codec.encode(long) + b"\x00", long, "the DATA a byte too long"),
        (codec.encode(short)[:-1], short, "the DATA a byte short"),
    ]
    for body, _, _ in sent:
        stream.probe.send_packet([DataPayload(STREAM_ID, body)])
    await _judge_echo(ctx, server, stream, access, newer, [(v, what) for _, v, what in sent])


@scenario_case(
    "rctp/client/stream-unknown-payload-skipped",
    "A payload of an unknown type is skipped by its length: the DATA after it in the packet is"
    " taken",
    ["R-RCTP-51"],
)
async def stream_unknown_payload_skipped(ctx: Context) -> None:
    hushed = await _hushed(ctx)
    _, _, access, codec, newer = hushed
    decoy, after = ({**newer, **mark} for mark in _marks(ctx, access, 2))
    # The unknown body looks like a DATA body of other values: read as one, it was not skipped;
    # the DATA after it holds values of its own, which show it was taken.
    unknown = UnknownPayload(UNKNOWN_TYPE, STREAM_ID, codec.encode(decoy))
    await _data_after(
        ctx, hushed, [unknown], after, (decoy, "the unknown payload's body, read as DATA")
    )


@scenario_case(
    "rctp/client/stream-broken-flow-beside-data",
    "FLOW bodies that are broken and no request (an ACK and a NACK a byte short, a body shorter"
    " than its preamble) are ignored: the DATA after them in their packet is taken",
    ["R-RCTP-53"],
)
async def stream_broken_flow_beside_data(ctx: Context) -> None:
    hushed = await _hushed(ctx)
    _, stream, access, _, newer = hushed
    after = {**newer, **_marks(ctx, access, 1)[0]}
    # D-RCTP-22: in a packet whose framing holds, a broken ACK or NACK, or a body shorter than
    # its preamble, is ignored and the packet's other payloads are handled. They come first: a
    # client that gives up on a packet at its first broken body never reaches the DATA.
    now = stream.robot_time()
    ack = HeartbeatAck(stream.probe.next_request_id(), now, now, now)
    nack = Nack(stream.probe.next_request_id(), Operation.GET_INTERVAL, NackReason.UNKNOWN_STREAM)
    bodies = [encode_flow(ack)[:-1], encode_flow(nack)[:-1], b"\x01\x02"]
    broken: list[Payload] = [MalformedFlowPayload(0, body, "sent broken", 0) for body in bodies]
    dropped = "the packet before: the one with the broken FLOW bodies not taken"
    await _data_after(ctx, hushed, broken, after, (newer, dropped))


async def _data_after(
    ctx: Context,
    hushed: Hushed,
    first: list[Payload],
    after: dict[str, Value],
    other: tuple[dict[str, Value], str],
) -> None:
    """After `_hushed`: a packet of the payloads `first`, then DATA of `after`, which the client
    must take, whatever it makes of `first` (`other`: values the client shows when it did not,
    and what they are)."""
    server, stream, access, codec, _ = hushed
    stream.probe.send_packet([*first, DataPayload(STREAM_ID, codec.encode(after))])
    await _judge_echo(ctx, server, stream, access, after, [other])


@scenario_case(
    "rctp/client/bye-while-streaming",
    "A server BYE while the stream plays is answered 200, and no DATA follows its answer",
    ["R-RCTP-23", "R-RCTP-44"],
)
async def bye_while_streaming(ctx: Context) -> None:
    await _ended_while_streaming(ctx, "BYE", "*", "shutdown", "R-RCTP-23")


@scenario_case(
    "rctp/client/stop-while-streaming",
    "A server STOP of the stream while it plays is answered 200, and no DATA follows its answer",
    ["R-RCTP-24", "R-RCTP-44"],
)
async def stop_while_streaming(ctx: Context) -> None:
    server = await _ended_while_streaming(ctx, "STOP", None, "test", "R-RCTP-24")
    await server.reach("BYE")  # D-RCTP-31: a STOP ends the stream's step; the run goes on


@scenario_case(
    "rctp/client/stop-while-paused",
    "A server STOP of the stream while it is paused (ready, D-RCTP-14: a STOP of a set-up"
    " access) is answered 200",
    ["R-RCTP-24"],
)
async def stop_while_paused(ctx: Context) -> None:
    server, _, access = await until_playing(ctx)
    paused = await server.reach("PAUSE", access.path)
    if paused is None or paused.status != 200:
        raise Inconclusive(f"the client did not PAUSE {access.path} (D-RCTP-31 step 6)")
    # Sent as the PAUSE's answer leaves: the client waits 0.25 s before its GO (step 6).
    probe = server.probe
    await probe.send(probe.request_bytes("STOP", format_target(access.path), [("Reason", "test")]))
    ctx.expect_status(await server.answer(), 200, "R-RCTP-24", what=f"STOP {access.path}, paused")
    await server.reach("BYE")


async def _ended_while_streaming(
    ctx: Context, method: str, target: str | None, reason: str, requirement: str
) -> PlayedServer:
    """The server's `method` of `target` (the stream access by default) once the stream plays:
    answered 200 (`requirement`), and no DATA of the client's after the answer, for a while."""
    server, stream, access = await until_playing(ctx)
    probe = server.probe
    target = target or format_target(access.path)
    await probe.send(probe.request_bytes(method, target, [("Reason", reason)]))
    answer = await server.answer()
    answered = asyncio.get_running_loop().time()
    ctx.expect_status(answer, 200, requirement)
    await asyncio.sleep(WATCH * ctx.scale)
    # One DATA may have been on its way when the answer left, and the loop lags a little.
    slack = (access.write_interval or 0.05) + 0.1 * ctx.scale
    late = [one.at - answered for one, _ in stream.data() if one.at > answered + slack]
    ctx.expect(
        not late,
        f"no DATA after the {method} was answered: the stream no longer plays",
        f"{plural(len(late), 'DATA payload')}, up to {max(late, default=0):.2f} s after",
        "R-RCTP-44",
        timing=True,
        by=max(late, default=slack) - slack,
    )
    return server


#: What `_hushed` gives: the played server, its stream, the stream's access, the codec of the
#: robot's DATA and the values of the good packet it sent.
Hushed = tuple[PlayedServer, PlayedStream, AccessNode, ValuesCodec[DataNode], dict[str, Value]]


async def _hushed(ctx: Context, start: int | None = None) -> Hushed:
    """The scenario up to its stream's GO (the played server's packets numbered from `start`,
    if given), the played robot's own DATA stopped (the case's packets are the only ones), and a
    good packet sent: the server, the stream, its access, the codec of the robot's DATA, and the
    good packet's values (its number is the probe's `last_sequence`)."""
    server, stream, access = await until_playing(ctx, start=start)
    stream.sending = False
    codec = stream_codec(access, Direction.READ)
    newer = {n.name: visible(n) for n in codec.nodes}
    stream.probe.send_packet([DataPayload(STREAM_ID, codec.encode(newer))])
    return server, stream, access, codec, newer


async def _judge_echo(
    ctx: Context,
    server: PlayedServer,
    stream: PlayedStream,
    access: AccessNode,
    newer: dict[str, Value],
    others: list[tuple[dict[str, Value], str]],
) -> None:
    """After `newer` went in a good packet and `others` in packets the client must not take,
    every DATA of the client's from two write intervals on holds `newer`'s shared values (the
    echo of step 6) until its PAUSE; the scenario is then run to its BYE."""
    shared = shared_nodes(access)
    # DATA the client sent before the packets reached it still carries what it had.
    settled = asyncio.get_running_loop().time() + 2 * (access.write_interval or 0.05)
    settled += 0.1 * ctx.scale
    await server.reach("PAUSE")
    echoed = written(stream, access, since=settled)
    if not echoed:
        raise Inconclusive("the client sent no DATA after the packets (step 6's echo)")

    def same(echo: dict[str, Value], values: dict[str, Value]) -> bool:
        return all(echo.get(n.name) == values[n.name] for n in shared)

    wrong = next((v for v in echoed if not same(v, newer)), None)
    source = next((what for values, what in others if wrong and same(wrong, values)), "")
    ctx.expect(
        wrong is None,
        f"{shown(shared, newer)} in every DATA after the packets: no other packet's values",
        f"DATA with {shown(shared, wrong)}" + (f", the values of {source}" if source else "")
        if wrong
        else "",
        ctx.case.requirements[0],
    )
    await server.reach("BYE")


def _marks(ctx: Context, access: AccessNode, count: int) -> list[dict[str, Value]]:
    """`count` values of one read-and-written number node of the access, each unlike the others,
    its zero and `visible`'s: what the client echoes names the packet it took."""
    for node in shared_nodes(access):
        kind = node.type.base.kind
        if node.type.is_array or kind not in (Kind.INTEGER, Kind.FLOAT):
            continue
        high = node.maximum if node.maximum is not None else min(1000, node.type.base.high)
        if kind is Kind.FLOAT:
            values: list[Value] = [high * (k + 1) / 8 for k in range(count)]
        else:
            values = [int(high) * (k + 1) // 8 for k in range(count)]
        if len({*values, node.zero(), visible(node)}) == count + 2:
            return [{node.name: v} for v in values]
    raise Inconclusive(f"{access.path} has no number node read and written with room for marks")
