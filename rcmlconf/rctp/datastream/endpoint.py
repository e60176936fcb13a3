"""One session's data stream at one end, either role, without I/O (specs/rctp-2.0.md §6).

As aioquic's connection: datagrams and a `now` go in (`receive_datagram`), events come out
(`next_event`), datagrams to send collect in `datagrams_to_send(now)`, and time is a value
(`get_timer()`, `handle_timer(now)`). DATA bodies come from the application, which alone knows
the robot's values: after `handle_timer`, `due(now)` names the playing streams whose interval has
come, and `send_data` sends their bodies, several streams in one packet (D-RCTP-20).

The endpoint keeps what the spec asks of a receiver — the sequence rules (D-RCTP-21), FLOW
answers remembered for repeated ids and requests sent again until answered (D-RCTP-22), the receive
timeout (D-RCTP-23), a client's heartbeats and clock estimate (D-RCTP-24) — so that the reference
server and client, and the conformance harness, get them from one place.

`now` is monotonic seconds; `unix_offset` turns it into the Unix time that NTP timestamps need.
"""

from __future__ import annotations

from collections import OrderedDict, deque
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass

from rcmlconf.errors import ProtocolError
from rcmlconf.rcml.model import AccessNode, DataNode
from rcmlconf.rctp.bodies import ValuesCodec
from rcmlconf.rctp.datastream.clock import ClockEstimator, ClockSample, ntp_from_unix
from rcmlconf.rctp.datastream.events import (
    ClockUpdated,
    FlowAnswered,
    FlowRequested,
    FlowUnanswered,
    PacketDropped,
    PayloadIgnored,
    StreamEvent,
    StreamTimedOut,
    ValuesReceived,
)
from rcmlconf.rctp.datastream.flow import (
    Direction,
    FlowMessage,
    HeartbeatAck,
    HeartbeatRequest,
    IntervalGet,
    IntervalGetAck,
    IntervalSet,
    IntervalSetAck,
    Message,
    Nack,
    NackReason,
    TimeoutGet,
    TimeoutGetAck,
    TimeoutSet,
    TimeoutSetAck,
    UnknownRequest,
    encode_flow,
)
from rcmlconf.rctp.datastream.order import Arrival, SequenceTracker
from rcmlconf.rctp.datastream.packets import (
    HEADER,
    MAX_DATAGRAM,
    MAX_PAYLOADS,
    PAYLOAD_HEADER,
    DataPayload,
    EncodedPayload,
    FlowPayload,
    MalformedFlowPayload,
    Packet,
    Payload,
    PayloadType,
    UnknownPayload,
    body_offsets,
    pull_packet,
    push_datagram,
)
from rcmlconf.rctp.datastream.values import stream_codec
from rcmlconf.rctp.errors import LocalProtocolError
from rcmlconf.rctp.states import Role

#: D-RCTP-22: a request is sent again every 250 ms until answered, five sends in all.
RETRY_EVERY = 0.25
SENDS = 5
#: D-RCTP-22: the answerer remembers its last 64 answers.
ANSWERS_KEPT = 64
#: Requests of this side waiting for an answer, at most: an application that asks faster than
#: answers come back is told so rather than buffered without bound.
MAX_OUTSTANDING = 64
#: R-RCTP-49 asks for a heartbeat at least every 10 s while a stream plays; the first comes at
#: once, so that the clock estimate is there from the start. A client may beat faster
#: (`Endpoint(heartbeat_every=...)`: D-RCTP-31's scenario beats every second).
HEARTBEAT_EVERY = 5.0
#: Streams due within this of each other leave in one packet (D-RCTP-20).
SEND_SLACK = 0.001
#: D-RCTP-22: a timeout beyond 32 bits is sent as the largest, meaning "at least that".
_MAX_MICROS = (1 << 32) - 1
_RULE_SOURCE = "R-RCTP-42"

Address = tuple[str, int]

#: Which direction each role sends: read is robot to client (D-RCML-6).
SENDS_DIRECTION = {Role.SERVER: Direction.READ, Role.CLIENT: Direction.WRITE}
#: D-RCTP-18: the directions of each `Transport` mode.
MODE_DIRECTIONS = {
    "read": frozenset({Direction.READ}),
    "write": frozenset({Direction.WRITE}),
    "both": frozenset({Direction.READ, Direction.WRITE}),
}


def micros(seconds: float) -> int:
    """RCML seconds as D-RCTP-22's microseconds, rounded, saturating at 32 bits."""
    return min(round(seconds * 1e6), _MAX_MICROS)


@dataclass(slots=True)
class Stream:
    """One set-up stream access of the session, as this end sees it."""

    id: int
    access: AccessNode
    mode: str
    #: The codecs of the directions the mode carries (D-RCTP-18).
    codecs: dict[Direction, ValuesCodec[DataNode]]
    #: Microseconds in force per direction; they start at the RCML's (D-RCTP-18).
    intervals: dict[Direction, int]
    timeouts: dict[Direction, int]
    playing: bool = False
    #: When this end's direction is next due; None while not playing.
    next_send: float | None = None
    #: When DATA of the received direction last arrived (or the stream started playing).
    last_data: float | None = None

    @property
    def directions(self) -> frozenset[Direction]:
        return frozenset(self.codecs)

    def shortest(self, direction: Direction) -> int:
        """D-RCML-6: the RCML's interval is the shortest flow control may set (R-RCTP-47)."""
        seconds = (
            self.access.read_interval if direction is Direction.READ else self.access.write_interval
        )
        return micros(seconds or 0.0)


@dataclass(slots=True)
class _Outstanding:
    stream: int
    request: FlowMessage
    sends: int
    next_retry: float


class Endpoint:
    def __init__(
        self,
        role: Role,
        tag: int,
        *,
        peer: Address | None = None,
        first_sequence: int = 0,
        unix_offset: float = 0.0,
        precision: float = 0.0,
        heartbeat_every: float = HEARTBEAT_EVERY,
    ) -> None:
        """`first_sequence` should be random (R-RCTP-41); `precision` is the robot's
        `timePrecision` (D-RCTP-24), for a client's clock estimate; `heartbeat_every` the seconds
        between a client's heartbeats while a stream plays."""
        self.role = role
        self.tag = tag
        #: Where packets go and the only source they are taken from (R-RCTP-42, R-RCTP-56).
        self.peer = peer
        self.streams: dict[int, Stream] = {}
        self.sequences = SequenceTracker()
        self.clock = ClockEstimator(precision)
        self.sends = SENDS_DIRECTION[role]
        self.receives = Direction.WRITE if self.sends is Direction.READ else Direction.READ
        self._unix_offset = unix_offset
        self._sequence = first_sequence & 0xFFFF
        self._events: deque[StreamEvent] = deque()
        #: DATA and FLOW payloads waiting to leave, in the order they were queued.
        self._pending: list[EncodedPayload] = []
        self._datagrams: list[bytes] = []
        self._next_request = 0
        self._outstanding: dict[int, _Outstanding] = {}
        self._answers: OrderedDict[int, FlowMessage] = OrderedDict()
        self._next_heartbeat: float | None = None
        self._heartbeat_every = heartbeat_every

    # -- streams -----------------------------------------------------------------------------

    def add_stream(self, stream_id: int, access: AccessNode, mode: str) -> Stream:
        """SETUP answered 200. A repeated SETUP (in `ready`, D-RCTP-14) keeps the id, the
        intervals and the timeouts, and may change the mode (D-RCTP-28)."""
        directions = MODE_DIRECTIONS[mode]
        old = self.streams.get(stream_id)
        intervals = {
            Direction.READ: micros(access.read_interval or 0.0),
            Direction.WRITE: micros(access.write_interval or 0.0),
        }
        timeouts = {
            Direction.READ: micros(access.read_timeout),
            Direction.WRITE: micros(access.write_timeout),
        }
        if old is not None:
            intervals.update(old.intervals)
            timeouts.update(old.timeouts)
        stream = Stream(
            stream_id,
            access,
            mode,
            {d: stream_codec(access, d) for d in sorted(directions)},
            intervals,
            timeouts,
        )
        self.streams[stream_id] = stream
        return stream

    def remove_stream(self, stream_id: int) -> None:
        """STOP answered 200 (either side's)."""
        self.streams.pop(stream_id, None)
        self._heartbeats_follow_play()

    def play(self, stream_id: int, now: float) -> None:
        """GO answered 200: sending starts now, and the receive timeout counts from now."""
        stream = self._stream(stream_id)
        if not stream.playing:
            stream.playing = True
            stream.next_send = now if self.sends in stream.codecs else None
            stream.last_data = now
        self._heartbeats_follow_play(now)

    def pause(self, stream_id: int) -> None:
        """PAUSE answered 200: nothing is sent or expected (R-RCTP-44)."""
        stream = self._stream(stream_id)
        stream.playing = False
        stream.next_send = stream.last_data = None
        self._heartbeats_follow_play()

    def _stream(self, stream_id: int) -> Stream:
        stream = self.streams.get(stream_id)
        if stream is None:
            raise LocalProtocolError(f"stream {stream_id} is not set up")
        return stream

    def _heartbeats_follow_play(self, now: float | None = None) -> None:
        """A client sends heartbeats while any stream plays (R-RCTP-49), the first at once."""
        if self.role is not Role.CLIENT:
            return
        if not any(stream.playing for stream in self.streams.values()):
            self._next_heartbeat = None
        elif self._next_heartbeat is None and now is not None:
            self._next_heartbeat = now

    # -- receiving ---------------------------------------------------------------------------

    def receive_datagram(self, data: bytes, addr: Address, now: float) -> bool:
        """One datagram from `addr`. True when it was the session's (it keeps the session alive,
        D-RCTP-11), whatever became of its payloads."""
        if self.peer is None or tuple(addr[:2]) != tuple(self.peer[:2]):
            self._events.append(
                PacketDropped(f"from {addr[0]}:{addr[1]}, not the session's peer", _RULE_SOURCE)
            )
            return False
        try:
            packet = pull_packet(data)
        except ProtocolError as error:
            self._events.append(
                PacketDropped(error.reason, error.rule or "R-RCTP-39", error.offset)
            )
            return False
        if packet.tag != self.tag:
            self._events.append(
                PacketDropped(f"tag {packet.tag:08x}, not the session's", _RULE_SOURCE, 4)
            )
            return False
        arrival = self.sequences.see(packet.sequence)
        for index, payload in enumerate(packet.payloads):
            _RECEIVE[type(payload)](self, packet, index, arrival, now)
        return True

    def _ignore(self, stream: int, reason: str, rule: str, offset: int | None = None) -> None:
        self._events.append(PayloadIgnored(stream, reason, rule, offset))

    def _receive_data(self, packet: Packet, index: int, arrival: Arrival, now: float) -> None:
        payload = packet.payloads[index]
        assert isinstance(payload, DataPayload)
        stream = self.streams.get(payload.stream)
        if stream is None or not stream.playing or self.receives not in stream.codecs:
            return self._ignore(
                payload.stream, "DATA of a stream not playing in this direction", "R-RCTP-44"
            )
        if arrival is not Arrival.NEWER:  # R-RCTP-43
            return self._ignore(payload.stream, f"DATA of a {arrival.value} packet", "R-RCTP-43")
        codec = stream.codecs[self.receives]
        try:
            values = codec.decode(payload.body, body_offsets(packet)[index])
        except ProtocolError as error:
            return self._ignore(
                payload.stream, error.reason, error.rule or codec.rule, error.offset
            )
        for node in codec.nodes:
            problem = node.out_of_range(values[node.name])
            if problem is not None:  # R-RCTP-58: none of the payload is applied
                return self._ignore(payload.stream, problem, "R-RCTP-58")
        stream.last_data = now
        self._events.append(ValuesReceived(payload.stream, values, packet.timestamp))
        return None

    def _receive_flow(self, packet: Packet, index: int, arrival: Arrival, now: float) -> None:
        # FLOW is handled in any packet, newer or not: request ids make it safe (D-RCTP-21).
        payload = packet.payloads[index]
        assert isinstance(payload, FlowPayload)
        if payload.flow.message is Message.REQUEST:
            self._answer(payload.stream, payload.flow, now)
        else:
            self._answered(payload.stream, payload.flow, now)

    def _receive_malformed_flow(
        self, packet: Packet, index: int, arrival: Arrival, now: float
    ) -> None:
        payload = packet.payloads[index]
        assert isinstance(payload, MalformedFlowPayload)
        self._ignore(payload.stream, payload.reason, payload.rule, payload.offset)
        reason, request_id, operation = payload.answer, payload.request_id, payload.operation
        if reason is not None and request_id is not None and operation is not None:
            self._queue(payload.stream, Nack(request_id, operation, reason))

    def _receive_unknown(self, packet: Packet, index: int, arrival: Arrival, now: float) -> None:
        payload = packet.payloads[index]
        assert isinstance(payload, UnknownPayload)
        self._ignore(payload.stream, f"payload type {payload.type}, skipped", "R-RCTP-51")

    # -- FLOW requests received --------------------------------------------------------------

    def _answer(self, stream_id: int, request: FlowMessage, now: float) -> None:
        """R-RCTP-46: ACK or NACK, and a repeated id gets the answer already given."""
        answer = self._answers.get(request.request_id)
        if answer is None:
            answer = _ANSWER[type(request)](self, stream_id, request, now)
            self._answers[request.request_id] = answer
            if len(self._answers) > ANSWERS_KEPT:
                self._answers.popitem(last=False)
            self._events.append(FlowRequested(stream_id, request, answer))
        self._queue(stream_id, answer)

    def _answer_heartbeat(self, stream_id: int, request: FlowMessage, now: float) -> FlowMessage:
        assert isinstance(request, HeartbeatRequest)
        # T2 and T3 are one instant: the answer leaves with the next datagrams_to_send(now).
        stamp = self.ntp(now)
        return HeartbeatAck(request.request_id, request.t1, stamp, stamp)  # R-RCTP-48

    def _answer_unknown(self, stream_id: int, request: FlowMessage, now: float) -> FlowMessage:
        assert isinstance(request, UnknownRequest)
        return Nack(request.request_id, request.operation, NackReason.UNKNOWN_OPERATION)

    def _flow_stream(self, stream_id: int, request: FlowMessage) -> Stream | Nack:
        """The stream a request concerns, or the NACK 2 for a stream or direction not set up."""
        direction = getattr(request, "direction", None)
        stream = self.streams.get(stream_id)
        if stream is None or direction not in stream.codecs:
            return Nack(request.request_id, request.operation, NackReason.UNKNOWN_STREAM)
        return stream

    def _answer_get(self, stream_id: int, request: FlowMessage, now: float) -> FlowMessage:
        stream = self._flow_stream(stream_id, request)
        if isinstance(stream, Nack):
            return stream
        if isinstance(request, IntervalGet):
            return IntervalGetAck(
                request.request_id, request.direction, stream.intervals[request.direction]
            )
        assert isinstance(request, TimeoutGet)
        return TimeoutGetAck(
            request.request_id, request.direction, stream.timeouts[request.direction]
        )

    def _answer_set(self, stream_id: int, request: FlowMessage, now: float) -> FlowMessage:
        """D-RCTP-22: the interval's owner is its sender, the timeout's its receiver."""
        stream = self._flow_stream(stream_id, request)
        if isinstance(stream, Nack):
            return stream
        rid, operation = request.request_id, request.operation
        if isinstance(request, IntervalSet):
            if request.direction is not self.sends:
                return Nack(rid, operation, NackReason.NOT_PERMITTED)
            if request.interval < max(stream.shortest(request.direction), 1):  # R-RCTP-47
                return Nack(rid, operation, NackReason.VALUE_REFUSED)
            stream.intervals[request.direction] = request.interval
            return IntervalSetAck(rid, request.direction, request.interval)
        assert isinstance(request, TimeoutSet)
        if request.direction is not self.receives:
            return Nack(rid, operation, NackReason.NOT_PERMITTED)
        if request.timeout < 2 * stream.intervals[request.direction]:  # R-RCTP-47
            return Nack(rid, operation, NackReason.VALUE_REFUSED)
        stream.timeouts[request.direction] = request.timeout
        return TimeoutSetAck(rid, request.direction, request.timeout)

    # -- FLOW answers received ---------------------------------------------------------------

    def _answered(self, stream_id: int, answer: FlowMessage, now: float) -> None:
        waiting = self._outstanding.get(answer.request_id)
        if waiting is None or waiting.request.operation != answer.operation:
            # An answer to a request given up on, or the second answer to one sent twice.
            return self._ignore(
                stream_id, f"{type(answer).__name__} answers no request", "R-RCTP-46"
            )
        del self._outstanding[answer.request_id]
        _RECORD.get(type(answer), _record_nothing)(self, waiting, answer, now)
        self._events.append(FlowAnswered(waiting.stream, waiting.request, answer))
        return None

    def _record_heartbeat(self, waiting: _Outstanding, answer: FlowMessage, now: float) -> None:
        assert isinstance(answer, HeartbeatAck)
        sample = ClockSample.from_times(answer.t1, answer.t2, answer.t3, self.ntp(now))
        self._events.append(ClockUpdated(self.clock.add(sample)))

    def _record_value(self, waiting: _Outstanding, answer: FlowMessage, now: float) -> None:
        """The peer's value in force, so that both ends agree on it."""
        stream = self.streams.get(waiting.stream)
        direction = getattr(answer, "direction", None)
        if stream is None or direction not in stream.codecs:
            return
        if isinstance(answer, IntervalGetAck | IntervalSetAck):
            stream.intervals[answer.direction] = answer.interval
        elif isinstance(answer, TimeoutGetAck | TimeoutSetAck):
            stream.timeouts[answer.direction] = answer.timeout

    # -- sending -----------------------------------------------------------------------------

    def ntp(self, now: float) -> int:
        """`now` as this end's NTP timestamp."""
        return ntp_from_unix(now + self._unix_offset)

    def request(self, build: Callable[[int], FlowMessage], stream: int, now: float) -> FlowMessage:
        """Send a FLOW request: `build` makes it from the request id. It is sent again until
        answered (D-RCTP-22); `FlowAnswered` or `FlowUnanswered` tells how it ended."""
        if len(self._outstanding) >= MAX_OUTSTANDING:
            raise LocalProtocolError(f"{MAX_OUTSTANDING} FLOW requests are waiting for answers")
        request_id = self._next_request
        self._next_request = (request_id + 1) & 0xFFFF
        request = build(request_id)
        if request.message is not Message.REQUEST or request.request_id != request_id:
            raise LocalProtocolError(f"{request!r} is not a request with id {request_id}")
        self._outstanding[request_id] = _Outstanding(stream, request, 1, now + RETRY_EVERY)
        self._queue(stream, request)
        return request

    def heartbeat(self, now: float) -> FlowMessage:
        """D-RCTP-24: T1 is `now`."""
        t1 = self.ntp(now)
        return self.request(lambda request_id: HeartbeatRequest(request_id, t1), 0, now)

    def due(self, now: float) -> tuple[int, ...]:
        """The playing streams whose interval has come: give `send_data` a body for each."""
        horizon = now + SEND_SLACK
        return tuple(
            stream.id
            for stream in self.streams.values()
            if stream.next_send is not None and stream.next_send <= horizon
        )

    def send_data(self, bodies: Mapping[int, bytes], now: float) -> None:
        """DATA bodies of playing streams (`Stream.codecs[...].encode`), in one packet as far
        as one holds them; each stream's next send is one interval on (R-RCTP-44)."""
        for stream_id, body in bodies.items():
            self._next_beat(stream_id, now)
            self._pending.append((PayloadType.DATA, body, stream_id))
        self._flush(now)

    def skip(self, stream_ids: Iterable[int], now: float) -> None:
        """Due streams with nothing to send (a client that has written no values yet): they
        wait for their next beat, sending nothing."""
        for stream_id in stream_ids:
            self._next_beat(stream_id, now)

    def _next_beat(self, stream_id: int, now: float) -> None:
        stream = self._stream(stream_id)
        if not stream.playing or self.sends not in stream.codecs:
            raise LocalProtocolError(f"stream {stream_id} does not play this end's direction")
        interval = stream.intervals[self.sends] * 1e-6
        # Keep the beat (the next is one interval after this one was due), unless the
        # application fell a whole interval behind: then start again from now, as a lost beat
        # is not made up (the newest values are the state, D-RCTP-20).
        after = (stream.next_send if stream.next_send is not None else now) + interval
        stream.next_send = after if after > now else now + interval

    def datagrams_to_send(self, now: float) -> list[bytes]:
        """Every datagram waiting, for the peer (`peer`)."""
        self._flush(now)
        datagrams, self._datagrams = self._datagrams, []
        return datagrams

    def _queue(self, stream: int, flow: FlowMessage) -> None:
        self._pending.append((PayloadType.FLOW, encode_flow(flow), stream))

    def _flush(self, now: float) -> None:
        """Pack what waits into as few packets as D-RCTP-19's limits allow."""
        payloads = self._pending
        if not payloads or self.peer is None:
            return
        self._pending = []
        stamp = self.ntp(now)
        batch: list[EncodedPayload] = []
        size = HEADER.size
        for payload in payloads:
            length = PAYLOAD_HEADER.size + len(payload[1])
            if batch and (len(batch) == MAX_PAYLOADS or size + length > MAX_DATAGRAM):
                self._packet(batch, stamp)
                batch, size = [], HEADER.size
            batch.append(payload)
            size += length
        self._packet(batch, stamp)

    def _packet(self, payloads: list[EncodedPayload], stamp: int) -> None:
        self._datagrams.append(push_datagram(self._sequence, self.tag, stamp, payloads))
        self._sequence = (self._sequence + 1) & 0xFFFF  # R-RCTP-41

    # -- timers ------------------------------------------------------------------------------

    def get_timer(self) -> float | None:
        """The earlier of `send_timer` and `maintenance_timer`."""
        send, other = self.send_timer(), self.maintenance_timer()
        if send is None or (other is not None and other < send):
            return other
        return send

    def send_timer(self) -> float | None:
        """When a stream is next due to send (`due`, `send_data`): a server with many sessions
        keeps their beats on one clock, apart from everything else (`maintenance_timer`)."""
        # Asked after every packet: a plain loop, no lists.
        timer = None
        for stream in self.streams.values():
            at = stream.next_send
            if at is not None and (timer is None or at < timer):
                timer = at
        return timer

    def maintenance_timer(self) -> float | None:
        """When `handle_timer` has work: a request to send again, a receive timeout, a
        heartbeat."""
        timer = self._next_heartbeat
        for waiting in self._outstanding.values():
            if timer is None or waiting.next_retry < timer:
                timer = waiting.next_retry
        receives = self.receives
        for stream in self.streams.values():
            if stream.last_data is not None and receives in stream.codecs:
                at = stream.last_data + stream.timeouts[receives] * 1e-6
                if timer is None or at < timer:
                    timer = at
        return timer

    def handle_timer(self, now: float) -> None:
        """Retries, receive timeouts and heartbeats; the data sends are the caller's (`due`)."""
        for request_id, waiting in list(self._outstanding.items()):
            if waiting.next_retry > now:
                continue
            if waiting.sends >= SENDS:
                del self._outstanding[request_id]
                self._events.append(FlowUnanswered(waiting.stream, waiting.request))
                continue
            waiting.sends += 1
            waiting.next_retry += RETRY_EVERY
            self._queue(waiting.stream, waiting.request)
        for stream in self.streams.values():
            if stream.last_data is None or self.receives not in stream.codecs:
                continue
            if now >= stream.last_data + stream.timeouts[self.receives] * 1e-6:
                stream.last_data = None  # watched again from the next GO
                self._events.append(StreamTimedOut(stream.id, self.receives))
        if self._next_heartbeat is not None and now >= self._next_heartbeat:
            self._next_heartbeat = now + self._heartbeat_every
            self.heartbeat(now)

    def next_event(self) -> StreamEvent | None:
        return self._events.popleft() if self._events else None


def _record_nothing(
    endpoint: Endpoint, waiting: _Outstanding, answer: FlowMessage, now: float
) -> None:
    """A NACK changes nothing: the value in force stays."""


_Receive = Callable[[Endpoint, Packet, int, Arrival, float], None]
#: Payload class -> what a receiver does with it.
_RECEIVE: dict[type[Payload], _Receive] = {
    DataPayload: Endpoint._receive_data,
    FlowPayload: Endpoint._receive_flow,
    MalformedFlowPayload: Endpoint._receive_malformed_flow,
    UnknownPayload: Endpoint._receive_unknown,
}
_Answer = Callable[[Endpoint, int, FlowMessage, float], FlowMessage]
#: Request class -> how it is answered (D-RCTP-22).
_ANSWER: dict[type[FlowMessage], _Answer] = {
    HeartbeatRequest: Endpoint._answer_heartbeat,
    IntervalGet: Endpoint._answer_get,
    TimeoutGet: Endpoint._answer_get,
    IntervalSet: Endpoint._answer_set,
    TimeoutSet: Endpoint._answer_set,
    UnknownRequest: Endpoint._answer_unknown,
}
_Record = Callable[[Endpoint, _Outstanding, FlowMessage, float], None]
#: Answer class -> what this end records of it.
_RECORD: dict[type[FlowMessage], _Record] = {
    HeartbeatAck: Endpoint._record_heartbeat,
    IntervalGetAck: Endpoint._record_value,
    IntervalSetAck: Endpoint._record_value,
    TimeoutGetAck: Endpoint._record_value,
    TimeoutSetAck: Endpoint._record_value,
}
