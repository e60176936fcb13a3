"""rctp/client, the scenario's data stream (D-RCTP-31 step 6): the packets an RCTP/2.0 client
under test sends while its stream plays (and none when no GO was answered 200), what it does with
the played robot's DATA (stale, out of range, well-formed), its FLOW answers and heartbeats, and
the clock estimate it writes in step 7 (R-RCTP-39 to R-RCTP-50, R-RCTP-58; specs/rctp-2.0.md
§6)."""

from __future__ import annotations

import asyncio
import itertools
import math
from collections.abc import Mapping

from rcmlconf.conformance.cases.rctp_client.scenario import edge, scenario_case
from rcmlconf.conformance.context import Context, outside_bounds
from rcmlconf.conformance.probes.played import PlayedServer, path_of, played
from rcmlconf.conformance.probes.played_stream import STREAM_ID, PlayedStream
from rcmlconf.conformance.probes.stream import flow_text
from rcmlconf.conformance.probes.stream_access import UNKNOWN_OPERATION
from rcmlconf.conformance.verdicts import Inconclusive
from rcmlconf.errors import ProtocolError
from rcmlconf.rcml.model import AccessNode, AccessType, DataNode, Permission
from rcmlconf.rctp.datastream import (
    DataPayload,
    Direction,
    FlowPayload,
    HeartbeatAck,
    HeartbeatRequest,
    IntervalGet,
    IntervalGetAck,
    IntervalSet,
    IntervalSetAck,
    Nack,
    NackReason,
    Operation,
    TimeoutSet,
    UnknownRequest,
    encode_flow,
    stream_codec,
)
from rcmlconf.rctp.datastream.clock import unix_from_ntp
from rcmlconf.rctp.datastream.endpoint import micros
from rcmlconf.rctp.messages import Request
from rcmlconf.values import Kind, Value
from rcmlconf.values.shown import values_text
from rcmlconf.wording import plural

#: D-RCTP-33: a span read off a sender's own timestamps is judged as up to 10 % longer than the
#: harness's clock shows, and 50 ms for the clock's granularity.
OWN_CLOCK_LONGER, OWN_CLOCK_GRAIN = 1.1, 0.05

#: Fewest DATA packets a client sends in the scenario's 2 s of play at the harness robot's
#: 50 ms write interval (20 where stream-pace doubles it), less a margin.
ENOUGH_DATA = 15
#: Streams whose first sequence numbers R-RCTP-41's random start is judged over.
RANDOM_STARTS = 3
#: How long the played server holds its answers to GO and to the RELEASE after a STOP.
HOLD = 0.6
#: How far apart two readings of the client's clock in one packet may be (they are taken as it
#: builds the packet; a second is far more than any client takes).
CLOCK_AGREEMENT = 1.0
#: The played robot's clock, ahead of the harness's (R-RCTP-50).
SKEW = 37.25


def stream_access(ctx: Context) -> AccessNode:
    return ctx.access(AccessType.STREAM, Permission.READ | Permission.WRITE)


async def until_playing(
    ctx: Context, holds: Mapping[str, float] | None = None, start: int | None = None
) -> tuple[PlayedServer, PlayedStream, AccessNode]:
    """The scenario run up to the GO of its stream (step 6), the played server holding its
    answers to the methods of `holds` that long from the start, and numbering its packets from
    `start` if given (else from its random start)."""
    access = stream_access(ctx)
    server = await played(ctx)
    server.holds.update(holds or {})
    if start is not None:
        await server.reach("SETUP", access.path)
        if server.stream is not None and not server.stream.received:  # nothing sent yet
            server.stream.probe.sequence = start
    go = await server.reach("GO", access.path)
    if go is None or server.stream is None:
        raise Inconclusive(f"the client did not SETUP and GO {access.path} (D-RCTP-31 step 6)")
    return server, server.stream, access


def written(
    stream: PlayedStream, access: AccessNode, since: float = -math.inf
) -> list[dict[str, Value]]:
    """The values of every DATA payload of the client's that decodes and arrived after `since`
    (loop time), in order."""
    codec = stream_codec(access, Direction.WRITE)
    found = []
    for one, payload in stream.data():
        if one.at <= since:
            continue
        try:
            found.append(codec.decode(payload.body))
        except ProtocolError:
            continue
    return found


@scenario_case(
    "rctp/client/stream-packets",
    "The client's data-stream packets: version 2, the session's tag, payloads that fill the"
    " datagram, DATA of exactly its writable values, FLOW bodies of their layout, numbered one"
    " more each time",
    ["R-RCTP-39", "R-RCTP-40", "R-RCTP-41", "R-RCTP-52"],
)
async def stream_packets(ctx: Context) -> None:
    server, stream, access = await until_playing(ctx)
    await server.reach("BYE")
    # A datagram that is no packet fails first: its DATA would not count below.
    for one in stream.received:
        if one.packet is None:
            ctx.expect(False, "packets of D-RCTP-19's layout", f"{one.error}", "R-RCTP-39")
    for broken in stream.malformed[:1]:  # its heartbeats and FLOW answers too
        ctx.expect(
            False,
            "FLOW bodies of D-RCTP-22's layout",
            f"{broken.reason}: {broken.body.hex(' ')}",
            "R-RCTP-52",
        )
    if len(stream.data()) < ENOUGH_DATA:
        raise Inconclusive(f"the client sent {plural(len(stream.data()), 'DATA payload')}")
    _random_start(ctx, stream)
    codec = stream_codec(access, Direction.WRITE)
    previous: int | None = None
    for one in stream.received:
        packet = one.packet
        assert packet is not None
        ctx.expect(
            packet.tag == stream.tag,
            f"tag {stream.tag:08x}",
            f"tag {packet.tag:08x}",
            "R-RCTP-39",
        )
        if previous is not None:
            ctx.expect(
                packet.sequence == (previous + 1) & 0xFFFF,
                f"sequence {(previous + 1) & 0xFFFF} after {previous}",
                f"sequence {packet.sequence}",
                "R-RCTP-41",
            )
        previous = packet.sequence
        for payload in packet.payloads:
            if isinstance(payload, FlowPayload) and isinstance(payload.flow, HeartbeatRequest):
                _same_clock(ctx, packet.timestamp, payload.flow.t1, "its heartbeat's T1")
            if isinstance(payload, DataPayload):
                ctx.expect(
                    payload.stream == STREAM_ID,
                    f"stream {STREAM_ID}",
                    f"stream {payload.stream}",
                    "R-RCTP-40",
                )
                try:
                    codec.decode(payload.body)
                except ProtocolError as error:
                    ctx.expect(
                        False,
                        f"DATA of {', '.join(codec.names)}",
                        f"{error.reason} at byte {error.offset}",
                        "R-RCTP-40",
                    )


@scenario_case(
    "rctp/client/stream-pace",
    "DATA once a write interval while the stream plays, at the interval a FLOW set request put in"
    " force, none before GO is answered, none while paused, none after STOP",
    ["R-RCTP-44"],
)
async def stream_pace(ctx: Context) -> None:
    # Slow answers to GO and to RELEASE (step 8, after the STOP) open windows in which DATA
    # sent at SETUP's answer or after STOP's shows.
    server, stream, access = await until_playing(ctx, {"GO": HOLD, "RELEASE": HOLD})
    interval, partly = await _slower(ctx, stream, access)
    await server.reach("BYE")
    go_at = [s.at for s in server.seen if s.names("GO", access.path)]
    stops = [
        s.at for s in server.seen if s.request.method in ("PAUSE", "STOP") and s.path == access.path
    ]
    times = [one.at for one, _ in stream.data()]
    if len(times) < ENOUGH_DATA or not stops:
        raise Inconclusive(f"the client sent {plural(len(times), 'DATA payload')} and no PAUSE")
    early = [t for t in times if t < go_at[0] - 0.01]
    ctx.expect(not early, "no DATA before GO was answered", f"{len(early)} before it", "R-RCTP-44")
    # Play spans: from each GO answered to the PAUSE or STOP after it.
    spans = []
    for start in go_at:
        end = min((t for t in stops if t > start), default=math.inf)
        spans.append((start, end))
    stamps = [unix_from_ntp(one.packet.timestamp) for one, _ in stream.data() if one.packet]
    _pace_in_own_clock(ctx, stamps, interval, partly)  # before the checks a held harness excuses
    if len(go_at) > 1:
        _paused_in_own_clock(ctx, stamps)
    _stopped_in_own_clock(ctx, _runs(stamps), spans)
    slack = interval + 0.1 * ctx.scale  # one in flight when the PAUSE left, and the loop's lag
    # How far outside every play each DATA came: a held harness moves a DATA by its holds at most.
    outside = [min(max(s - 0.01 - t, t - e - slack) for s, e in spans) for t in times]
    stray = [far for far in outside if far > 0]
    ctx.expect(
        not stray,
        "no DATA while paused or stopped",
        f"{len(stray)} DATA payloads outside the play, up to {max(stray, default=0):.2f} s",
        "R-RCTP-44",
        timing=True,
        by=max(stray, default=0.0),
    )
    for start, end in spans:
        inside = [t for t in times if start <= t <= end]
        if end is math.inf or end - start < 9 * interval:
            continue
        expected = (end - start) / interval
        low, high = 0.5 * expected, 1.5 * expected + 2
        ctx.expect(  # D-RCTP-33's bounds for a client
            low <= len(inside) <= high,
            f"about {expected:.0f} DATA payloads in {end - start:.2f} s at {interval * 1000:g} ms"
            f"{partly}",
            f"{len(inside)}",
            "R-RCTP-44",
            timing=True,
            by=outside_bounds(len(inside), low, high) * interval,
        )


#: What the played server answers the GOs of the stream with: the first a status below 200,
#: which is no interim answer in RCTP (D-RCTP-6: a response answers the oldest request still
#: unanswered), any later one a refusal of D-RCTP-15's. Neither is the 200 that makes it play.
_FIRST_GO, _LATER_GO = (100, "Continue"), (503, "Service Unavailable")


@scenario_case(
    "rctp/client/stream-go-not-ok",
    f"No DATA when no GO of the stream is answered 200 (the first is answered {_FIRST_GO[0]},"
    f" any later one {_LATER_GO[0]}): the stream never plays (D-RCTP-31: no DATA before a GO"
    " answered 200)",
    ["R-RCTP-44"],
)
async def stream_go_not_ok(ctx: Context) -> None:
    access = stream_access(ctx)
    server = await played(ctx)
    answered: list[int] = []

    def own(request: Request) -> bytes | None:
        if request.method != "GO" or path_of(request) != access.path:
            return None
        status, reason = _LATER_GO if answered else _FIRST_GO
        answered.append(status)
        return server.probe.response_bytes(request, status, reason)

    server.own = own
    go = await server.reach("GO", access.path)
    if go is None or server.stream is None:
        raise Inconclusive(f"the client did not SETUP and GO {access.path} (D-RCTP-31 step 6)")
    # The client's next request waits for its answer as a slow server's would (within the 5 s of
    # D-RCTP-31): a client that took the GO for answered 200 plays meanwhile.
    await asyncio.sleep(HOLD)
    await server.reach("BYE")
    times = [one.at - go.at for one, _ in server.stream.data()]
    ctx.expect(
        not times,
        f"no DATA: the GOs of {access.path} were answered {', '.join(map(str, answered))},"
        " so it never played",
        f"{plural(len(times), 'DATA payload')}, the first at {min(times, default=0):+.2f} s"
        " from the first GO's answer",
        "R-RCTP-44",
    )


def _pace_in_own_clock(ctx: Context, stamps: list[float], interval: float, partly: str) -> None:
    """D-RCTP-33's most DATA over a play, read off the client's own clock (its DATA's
    timestamps, D-RCTP-19, which do not depend on when a held harness read them), play by play
    (`_runs`)."""
    for run in _runs(stamps):
        spanned = (run[-1] - run[0]) / interval
        if spanned < 9:
            continue
        ctx.expect(
            len(run) <= 1.5 * spanned + 2,
            f"at most {1.5 * spanned + 2:.0f} DATA payloads in {run[-1] - run[0]:.2f} s of its"
            f" own clock at {interval * 1000:g} ms{partly}",
            f"{len(run)}",
            "R-RCTP-44",
        )


def _runs(stamps: list[float]) -> list[list[float]]:
    """The plays in the client's own clock: the runs of its DATA's timestamps between gaps of
    `HOLD` / 2 (the pause, `_paused_in_own_clock`)."""
    runs: list[list[float]] = []
    for stamp in stamps:
        if not runs or stamp - runs[-1][-1] >= HOLD / 2:
            runs.append([])
        runs[-1].append(stamp)
    return runs


def _stopped_in_own_clock(
    ctx: Context, runs: list[list[float]], spans: list[tuple[float, float]]
) -> None:
    """No DATA after STOP, read off the client's own clock: the last play's DATA were sent after
    the client had GO's answer and before it sent STOP, so in its own timestamps (D-RCTP-19) they
    span no more than the harness saw from sending that answer to reading the STOP, by a clock
    within D-RCTP-33's 10 %. The RELEASE after the STOP is answered `HOLD` late: a client that
    sends on until it ends the session shows a last play that much longer, however late the
    harness read its packets (a held harness only lengthens what it allows)."""
    if len(runs) != len(spans) or spans[-1][1] == math.inf:
        return  # the plays do not pair up: the pause's own check says why
    start, end = spans[-1]
    allowed = OWN_CLOCK_LONGER * (end - start) + OWN_CLOCK_GRAIN
    spanned = runs[-1][-1] - runs[-1][0]
    ctx.expect(
        spanned <= allowed,
        f"its last play's DATA within {allowed:.2f} s of its own clock: from the GO's answer to"
        " its STOP, none after it",
        f"{spanned:.2f} s",
        "R-RCTP-44",
    )


def _paused_in_own_clock(ctx: Context, stamps: list[float]) -> None:
    """The pause, read off the client's own clock: its DATA's timestamps (D-RCTP-19) do not
    depend on when the harness read the packets, so a held harness cannot excuse a client that
    sends through its pause. The GO that ends it is answered `HOLD` late: a client that stops
    while paused shows a gap that long in them (half of it, for a clock that runs slow)."""
    longest = max((b - a for a, b in itertools.pairwise(stamps)), default=0.0)
    ctx.expect(
        longest >= HOLD / 2,
        f"a gap of {HOLD / 2:g} s or more in the timestamps of its DATA: none while paused (the"
        f" GO after the PAUSE answered {HOLD:g} s late)",
        f"the longest gap {longest:.3f} s",
        "R-RCTP-44",
    )


def _random_start(ctx: Context, stream: PlayedStream) -> None:
    """R-RCTP-41's random start, over this run's first packet and those of the run's earlier
    cases: a start that never changes is no random one (all alike by chance: 1 in 2**32)."""
    listener = ctx.target.clients
    starts = (listener.stream_starts if listener is not None else []) + stream.first_sequence()
    if len(starts) < RANDOM_STARTS:
        ctx.cannot_check(
            f"the random start of R-RCTP-41, judged over {RANDOM_STARTS} streams of a run: this"
            f" run had {len(starts)} when the case ended"
        )
        return
    ctx.expect(
        len(set(starts)) > 1,
        f"sequence numbers starting at a random value: {len(starts)} streams, not all alike",
        f"every one started at {starts[0]}",
        "R-RCTP-41",
    )


async def _slower(ctx: Context, stream: PlayedStream, access: AccessNode) -> tuple[float, str]:
    """Ask the client to double its write interval (D-RCTP-22: its own, as the sender's): the
    interval in force, in seconds, and what the check of the pace loses if it was refused."""
    rcml = access.write_interval or 0.05
    ask = IntervalSet(stream.probe.next_request_id(), Direction.WRITE, micros(2 * rcml))
    answer = await stream.ask(ask, STREAM_ID)
    if isinstance(answer, IntervalSetAck) and answer.direction is Direction.WRITE:
        return answer.interval / 1e6, ""
    ctx.cannot_check(
        f"DATA at an interval a FLOW set put in force: the request for {2 * rcml * 1000:g} ms got"
        f" {flow_text(answer)}"
    )
    return rcml, " (the RCML's)"


@scenario_case(
    "rctp/client/flow-answers",
    "The client answers FLOW requests: get interval with its write interval, a set below the"
    " RCML's with NACK 3, a repeated id with the answer already given (after the interval"
    " changed), a read timeout below twice the read interval with NACK 3, a set of the read"
    " interval (the server's) with NACK 4, a get interval with a byte too many with NACK 5, an"
    " unknown operation with NACK 1, a stream not set up with NACK 2",
    ["R-RCTP-46", "R-RCTP-47", "R-RCTP-53", "R-RCTP-52"],
)
async def flow_answers(ctx: Context) -> None:
    server, stream, access = await until_playing(ctx)
    probe = stream.probe
    interval = micros(access.write_interval or 0.0)
    ask = IntervalGet(probe.next_request_id(), Direction.WRITE)
    first = await stream.ask(ask, STREAM_ID)
    ctx.expect(
        isinstance(first, IntervalGetAck) and first.interval == interval,
        f"IntervalGetAck (direction=write, interval={interval})",
        flow_text(first),
        "R-RCTP-46",
    )
    too_short = IntervalSet(probe.next_request_id(), Direction.WRITE, interval // 2)
    short = await stream.ask(too_short, STREAM_ID)
    ctx.expect(
        isinstance(short, Nack) and short.reason is NackReason.VALUE_REFUSED,
        "NACK 3 (value refused): below the RCML's write interval",
        flow_text(short),
        "R-RCTP-47",
    )
    # A changed interval makes a fresh answer to the repeated get differ from the one given.
    changed = await stream.ask(
        IntervalSet(probe.next_request_id(), Direction.WRITE, 2 * interval), STREAM_ID
    )
    if not isinstance(changed, IntervalSetAck) or changed.interval == interval:
        ctx.cannot_check(
            "the answer already given to a repeated id, once the interval changed: the set"
            f" request got {flow_text(changed)}"
        )
    again = await stream.ask(ask, STREAM_ID)
    ctx.expect(
        again == first,
        f"the answer already given, {flow_text(first)} (not the interval now in force)",
        flow_text(again),
        "R-RCTP-46",
    )
    # D-RCTP-22: the client receives the read direction, so it owns its timeout too.
    reads = micros(access.read_interval or 0.0)
    short_timeout = TimeoutSet(probe.next_request_id(), Direction.READ, reads * 3 // 2)
    refused = await stream.ask(short_timeout, STREAM_ID)
    ctx.expect(
        isinstance(refused, Nack) and refused.reason is NackReason.VALUE_REFUSED,
        f"NACK 3 (value refused): a read timeout of {reads * 3 // 2} us, below twice the read"
        f" interval of {reads} us",
        flow_text(refused),
        "R-RCTP-47",
    )
    await _read_interval_not_owned(ctx, stream, 2 * reads)
    # D-RCTP-22: a get request's fields are its direction, one byte; one more does not fit.
    extra = probe.next_request_id()
    malformed = await stream.ask_broken(
        encode_flow(IntervalGet(extra, Direction.WRITE)) + b"\x00", extra, STREAM_ID
    )
    ctx.expect(
        isinstance(malformed, Nack) and malformed.reason is NackReason.MALFORMED,
        "NACK 5 (malformed): a get interval with a byte after its direction",
        flow_text(malformed),
        "R-RCTP-53",
    )
    unknown = UnknownRequest(probe.next_request_id(), UNKNOWN_OPERATION, b"\x01\x02\x03")
    nack = await stream.ask(unknown, STREAM_ID)
    ctx.expect(
        isinstance(nack, Nack) and nack.reason is NackReason.UNKNOWN_OPERATION,
        f"NACK 1 (unknown operation) to operation {UNKNOWN_OPERATION}",
        flow_text(nack),
        "R-RCTP-53",
    )
    # D-RCTP-22: a client that answers for its one stream whatever the id asks about answers
    # a stream the session never set up with that stream's interval.
    nowhere = STREAM_ID + 1
    elsewhere = await stream.ask(IntervalGet(probe.next_request_id(), Direction.WRITE), nowhere)
    ctx.expect(
        isinstance(elsewhere, Nack)
        and elsewhere.reason is NackReason.UNKNOWN_STREAM
        and elsewhere.operation == Operation.GET_INTERVAL,
        f"NACK 2 (unknown stream) of operation {Operation.GET_INTERVAL}: stream {nowhere} was"
        " never set up",
        flow_text(elsewhere),
        "R-RCTP-46",
    )
    await server.reach("BYE")


async def _read_interval_not_owned(ctx: Context, stream: PlayedStream, interval: int) -> None:
    """D-RCTP-22: the read interval belongs to its sender, the server: a set request of it to the
    client is NACK 4. `interval` is above the RCML's, so only the owner is wrong (not NACK 3)."""
    if stream.mode == "write":  # no read direction: NACK 2, whoever owns the interval
        ctx.cannot_check("NACK 4 to a set of the read interval: the client's stream only writes")
        return
    ask = IntervalSet(stream.probe.next_request_id(), Direction.READ, interval)
    answer = await stream.ask(ask, STREAM_ID)
    ctx.expect(
        isinstance(answer, Nack)
        and answer.reason is NackReason.NOT_PERMITTED
        and answer.operation == Operation.SET_INTERVAL,
        f"NACK 4 (not permitted) of operation {Operation.SET_INTERVAL}: a set of the read"
        f" interval to {interval} us, which the server owns as its sender",
        flow_text(answer),
        "R-RCTP-46",
    )


@scenario_case(
    "rctp/client/heartbeat-ack",
    "The client answers a heartbeat of the server's with its T1 echoed and its T2 and T3",
    ["R-RCTP-48", "R-RCTP-46", "R-RCTP-52"],
)
async def heartbeat_ack(ctx: Context) -> None:
    server, stream, _ = await until_playing(ctx)
    t1 = stream.robot_time()
    answer = await stream.ask(HeartbeatRequest(stream.probe.next_request_id(), t1))
    ctx.expect(isinstance(answer, HeartbeatAck), "HeartbeatAck", flow_text(answer), "R-RCTP-48")
    assert isinstance(answer, HeartbeatAck)
    ctx.expect(answer.t1 == t1, f"T1 {t1} echoed", f"T1 {answer.t1}", "R-RCTP-48")
    ctx.expect(answer.t3 >= answer.t2, "T3 not before T2", flow_text(answer), "R-RCTP-48")
    carried = [
        one.packet
        for one in stream.received
        if one.packet is not None
        and any(isinstance(p, FlowPayload) and p.flow == answer for p in one.packet.payloads)
    ]
    for packet in carried[:1]:
        _same_clock(ctx, packet.timestamp, answer.t2, "T2", "R-RCTP-48")
    await server.reach("BYE")


@scenario_case(
    "rctp/client/heartbeats",
    "While its stream plays the client sends heartbeats (D-RCTP-31: at GO, then every second)",
    ["R-RCTP-49"],
)
async def heartbeats(ctx: Context) -> None:
    server, stream, _ = await until_playing(ctx)
    await server.reach("BYE")
    beats = [f for _, f in stream.flow_requests if isinstance(f, HeartbeatRequest)]
    ctx.expect(
        len(beats) >= 2,
        "a heartbeat at GO and more while the stream plays (2 or 3 in the scenario)",
        plural(len(beats), "heartbeat"),
        "R-RCTP-49",
    )


@scenario_case(
    "rctp/client/clock-estimate",
    "The clock offset the client estimates from heartbeats (written in step 7) is the played"
    " robot's, within its stated uncertainty, which is no better than timePrecision",
    ["R-RCTP-50"],
)
async def clock_estimate(ctx: Context) -> None:
    server = await played(ctx)
    clock = ctx.robot.node("/clock")
    if not isinstance(clock, AccessNode):
        raise Inconclusive("the robot has no clock access (D-RCTP-31 step 7)")
    access = stream_access(ctx)
    setup = await server.reach("SETUP", access.path)
    if setup is None or server.stream is None:
        raise Inconclusive("the client set up no stream (D-RCTP-31 step 6)")
    server.stream.skew = SKEW
    await server.reach("BYE")
    writes = {w.path: w.values for w in server.writes}
    offset = writes.get("/clock/offset", {}).get("offset")
    uncertainty = writes.get("/clock/uncertainty", {}).get("uncertainty")
    if not isinstance(offset, float) or not isinstance(uncertainty, float):
        raise Inconclusive("the client wrote no clock estimate (D-RCTP-31 step 7)")
    precision = ctx.robot.time_precision or 0.0
    ctx.expect(
        uncertainty >= precision,
        f"an uncertainty of at least timePrecision, {precision:g} s",
        f"{uncertainty:g} s",
        "R-RCTP-50",
    )
    ctx.expect(
        abs(offset - SKEW) <= uncertainty + 0.05 * ctx.scale,
        f"an offset of {SKEW:g} s (the played robot's clock is that far ahead), within"
        f" {uncertainty:g} s",
        f"{offset:g} s",
        "R-RCTP-50",
    )


def _same_clock(
    ctx: Context, header: int, carried: int, what: str, requirement: str = "R-RCTP-39"
) -> None:
    """A packet's timestamp and a time its FLOW payload carries are both the sender's clock in
    NTP format, taken as it sent (D-RCTP-19, D-RCTP-22): whatever the sender's clock reads, they
    agree. (A count from 1970 is 2,208,988,800 s off.)"""
    apart = unix_from_ntp(header) - unix_from_ntp(carried)
    ctx.expect(
        abs(apart) <= CLOCK_AGREEMENT,
        f"the packet's timestamp and {what} within {CLOCK_AGREEMENT:g} s: both are the client's"
        " clock, in NTP format",
        f"{apart:+.3f} s apart",
        requirement,
    )


def shown(nodes: list[DataNode], values: dict[str, Value]) -> str:
    return ", ".join(values_text(nodes, values))


def shared_nodes(access: AccessNode) -> list[DataNode]:
    """The access's nodes that are read and written: DATA's echo shows what was taken."""
    return [n for n in access.data if Permission.READ | Permission.WRITE in n.permission]


def visible(node: DataNode) -> Value:
    """A value of the node unlike its zero, within its range (a number; else its edge)."""
    if node.type.base.kind is Kind.FLOAT:
        return (node.maximum if node.maximum is not None else 1000) / 2
    if node.type.base.kind is Kind.INTEGER:
        high = node.maximum if node.maximum is not None else min(1000, node.type.base.high)
        return max(1, int(high) // 2)
    return edge(node, high=True)
