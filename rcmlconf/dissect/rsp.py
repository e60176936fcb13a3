"""RSP seen from the wire (specs/rsp.md §2, §3).

Every datagram's header is read by the core's header rules (D-RSP-10, R-RSP-13): any model's
without `--model`, the model's own with it. With a model the whole packet is read by its
`RspCodec` (Device Map and payloads, D-RSP-14); without one, the session bodies (HELLO ... PERIOD)
are still read, since they need no model, and a map body is shown as its bytes. An encrypted
session's bodies (D-RSP-21) are shown as bytes: the dissector holds no key.

A stream is one sender's packets of one session: sequence numbers through the core's
`SequenceTracker` (D-RSP-15), millisecond timestamps into RFC 3550's jitter. A session is found by
its HELLO and WELCOME (D-RSP-12), HELLO to WELCOME timed; with a model, reliable occurrences are
paired with their ACKs (D-RSP-17): occurrences sent again, and the time to the first ACK.
"""

from __future__ import annotations

import statistics
from dataclasses import dataclass
from typing import Any, NamedTuple

from rcmlconf.buffer import Buffer
from rcmlconf.dissect.context import Context
from rcmlconf.dissect.records import RSP, Malformed, Record, Severity, make_record
from rcmlconf.dissect.streams import Stream
from rcmlconf.errors import ProtocolError
from rcmlconf.rsp.codec import RspCodec
from rcmlconf.rsp.codec.bodies import (
    BODIES,
    Body,
    Bye,
    Hello,
    MapBody,
    Period,
    Refused,
    Welcome,
    pull_session_body,
)
from rcmlconf.rsp.codec.header import (
    ANY,
    TYPE_AT,
    Encryption,
    Header,
    HeaderRules,
    PacketType,
)
from rcmlconf.rsp.layout import HEADER_SIZE
from rcmlconf.rsp.model import DeviceKind

_HELLO, _WELCOME, _REFUSED = PacketType.HELLO, PacketType.WELCOME, PacketType.REFUSED
_DOWNLINK, _UPLINK, _ACK = PacketType.DOWNLINK, PacketType.UPLINK, PacketType.ACK
_BYE, _PERIOD = PacketType.BYE, PacketType.PERIOD
_NAMES = {member: member.name for member in PacketType}
_new = tuple.__new__
_MAPS = frozenset({_DOWNLINK, _UPLINK, _ACK})
#: Never sealed (D-RSP-21): HELLO and WELCOME carry a MAC; REFUSED belongs to no session.
_PLAIN = frozenset({_HELLO, _WELCOME, _REFUSED})
_NONE = Encryption.NONE
_RELIABLE = frozenset({DeviceKind.COMMAND, DeviceKind.MEMORY_COMMAND, DeviceKind.MEMORY_EVENT})
_COMMAND = DeviceKind.COMMAND
#: The bits of a session ID shown in a summary.
RULE = "R-RSP-14"


class RspPacket(NamedTuple):
    """`Record.value` of an RSP packet: the header, and the body as far as it could be read —
    the core's body, or its bytes (a map body without a model; an encrypted body)."""

    header: Header
    body: Body | bytes


@dataclass(frozen=True, slots=True)
class RspSessionReport:
    session: str
    local: str
    robot: str
    model_id: int
    encryption: str
    #: Milliseconds: asked by HELLO, in force after WELCOME, and each PERIOD's.
    periods: tuple[int, ...]
    #: HELLO (the first of its nonce) to WELCOME, seconds.
    handshake: float | None
    hellos: int
    #: BYE's reason and who sent it, if the session was ended in the capture.
    ended: str | None
    #: With a model (D-RSP-17): reliable occurrences, the memory commands and memory events sent
    #: again (and how many sends that took), those acknowledged, and first send to first ACK:
    #: min, median, max seconds.
    occurrences: int
    repeated: int
    resends: int
    acknowledged: int
    ack_time: tuple[float, float, float] | None
    first: float
    last: float


class _Session:
    __slots__ = (
        "ack_times",
        "acked",
        "encryption",
        "ended",
        "first",
        "handshake",
        "hello",
        "id",
        "last",
        "local",
        "model_id",
        "occurrences",
        "periods",
        "robot",
    )

    def __init__(self, session_id: int, local: str, robot: str, header: Header, time: float):
        self.id = session_id
        self.local = local
        self.robot = robot
        self.model_id = header.model_id
        self.encryption = header.encryption
        self.periods: list[int] = []
        self.handshake: float | None = None
        #: [first HELLO's time, its period, HELLOs sent, robot] of the session's nonce.
        self.hello: list[Any] | None = None
        self.ended: str | None = None
        #: (device, id) -> [first send, sends]
        self.occurrences: dict[tuple[int, int], list[float]] = {}
        self.acked: set[tuple[int, int]] = set()
        self.ack_times: list[float] = []
        self.first = time
        self.last = time


class RspFlow:
    """What an RSP direction keeps: its streams by session ID, the last one at hand."""

    __slots__ = ("destination", "expected", "hellos", "session", "source", "stream", "streams")

    def __init__(self, source: str, destination: str) -> None:
        self.source = source
        self.destination = destination
        #: The encryption and model ID of the session at hand, once its WELCOME was seen.
        self.expected: tuple[Encryption, int] | None = None
        #: HELLOs went this way since the last session: its packets of session 0 open the next.
        self.hellos = False
        self.session = -1
        #: The stream of `session`: set with it, before it is read.
        self.stream: Stream = None  # type: ignore[assignment]
        self.streams: dict[int, Stream] = {}


class RspDecoder:
    def __init__(self, ctx: Context) -> None:
        self.ctx = ctx
        model = ctx.options.rsp_model
        self.model = model
        self.codec = RspCodec(model) if model is not None else None
        self.rules: HeaderRules = self.codec.rules if self.codec is not None else ANY
        self.kinds = tuple(d.kind for d in model.devices) if model is not None else ()
        self.sessions: dict[int, _Session] = {}
        #: (local, client nonce) -> (time of the first HELLO, its period, HELLOs sent).
        self._hellos: dict[tuple[str, bytes], list[Any]] = {}
        #: The newest HELLO of each local system, for a REFUSED.
        self._last_hello: dict[str, tuple[str, bytes]] = {}
        #: Datagrams that could not be read (the others are counted by their streams).
        self.malformed = 0

    def datagram(
        self, flow: Any, state: RspFlow, time: float, frame: int, payload: bytes, where: int
    ) -> None:
        ctx = self.ctx
        number = ctx.count = ctx.count + 1
        codec = self.codec
        # D-RSP-12: REFUSED echoes the HELLO's model ID, whatever model sent the HELLO.
        refused = len(payload) > TYPE_AT and payload[TYPE_AT] == _REFUSED
        try:
            header = (ANY if refused else self.rules).pull(payload)
            _, model_id, encryption, kind, sequence, stamp, session_id, _, _ = header
            mapped = kind in _MAPS
            if encryption is not _NONE and kind not in _PLAIN:
                value: Any = _new(RspPacket, (header, payload[HEADER_SIZE:]))
            elif codec is not None and not refused:
                value = codec.pull_packet(payload)
            elif mapped:
                value = _new(RspPacket, (header, payload[HEADER_SIZE:]))
            else:
                value = _new(RspPacket, (header, self._session_body(header, payload)))
        except ProtocolError as error:
            self._malformed(flow, time, frame, number, error, where, payload)
            return
        stream = state.stream if session_id == state.session else self._stream(state, header)
        stream.see(time, sequence, stamp / 1000, len(payload))
        if not mapped:
            self._session_packet(state, header, value.body, time, frame, number)
        elif codec is not None and type(value.body) is MapBody:
            self._occurrences(header, value.body, time)
        expected = state.expected
        if expected is None and session_id in self.sessions:
            expected = state.expected = self._expected(session_id)
        if expected is not None and (encryption is not expected[0] or model_id != expected[1]):
            self._mismatch(state, header, expected, frame, time, number)
        ctx.emit(
            _new(Record, (number, frame, time, flow, _NAMES[kind], sequence, value, None, None))
        )

    @staticmethod
    def _session_body(header: Header, payload: bytes) -> Body:
        """HELLO ... PERIOD need no model (D-RSP-11); offsets from the datagram's start."""
        try:
            return pull_session_body(
                BODIES[header.type],  # type: ignore[arg-type]
                header,
                Buffer(payload[HEADER_SIZE:]),
            )
        except ProtocolError as error:
            raise ProtocolError(error.reason, HEADER_SIZE + error.offset, error.rule) from None

    def _expected(self, session_id: int) -> tuple[Encryption, int] | None:
        session = self.sessions.get(session_id)
        return (session.encryption, session.model_id) if session is not None else None

    def _mismatch(
        self,
        state: RspFlow,
        header: Header,
        expected: tuple[Encryption, int],
        frame: int,
        time: float,
        number: int,
    ) -> None:
        encryption, model_id = expected
        self.ctx.findings.add(
            Severity.ERROR,
            "R-RSP-13",
            f"{state.source} → {state.destination}: {_NAMES[header.type]} with model ID"
            f" {header.model_id} and encryption {header.encryption.name} in a session of"
            f" {model_id} and {encryption.name}",
            frame,
            time,
            number,
        )

    def _malformed(
        self,
        flow: Any,
        time: float,
        frame: int,
        number: int,
        error: ProtocolError,
        where: int,
        payload: bytes,
    ) -> None:
        self.malformed += 1
        try:
            header: Header | None = self.rules.pull(payload)
        except ProtocolError:
            header = None
        rule = error.rule or "R-RSP-16"
        located = where + error.offset if where >= 0 else None
        malformed = Malformed(error.reason, error.offset, rule, located)
        kind = _NAMES.get(header.type, "malformed") if header is not None else "malformed"
        self.ctx.findings.add(
            Severity.ERROR,
            rule,
            f"{flow.source} → {flow.destination}: a malformed {kind if header else 'RSP'} packet:"
            f" {error.reason} (byte {error.offset}); a receiver drops it (R-RSP-18)",
            frame,
            time,
            number,
            located,
        )
        value = RspPacket(header, b"") if header is not None else None
        sequence = header.sequence if header is not None else None
        self.ctx.emit(make_record(number, frame, time, flow, kind, sequence, value, malformed))

    # -- streams and sessions --------------------------------------------------------------------

    def _stream(self, state: RspFlow, header: Header) -> Stream:
        session_id = header.session_id
        stream = state.streams.get(session_id)
        if stream is None:
            previous = state.stream
            if previous is not None and state.session == 0 and session_id and state.hellos:
                # D-RSP-12: the HELLOs (session ID 0) were this session's first packets.
                stream = previous
                stream.session = f"{session_id:012x}"
                del state.streams[0]
                state.hellos = False
            else:
                stream = self.ctx.stream(
                    RSP, state.source, state.destination, f"{session_id:012x}", RULE
                )
            state.streams[session_id] = stream
        state.session = session_id
        state.stream = stream
        state.expected = None
        return stream

    def _session_packet(
        self,
        state: RspFlow,
        header: Header,
        body: Body | bytes,
        time: float,
        frame: int,
        number: int,
    ) -> None:
        kind = header.type
        findings = self.ctx.findings
        if kind is _HELLO and isinstance(body, Hello):
            key = (state.source, body.client_nonce)
            hello = self._hellos.get(key)
            if hello is None:
                self._hellos[key] = [time, body.period_ms, 1, state.destination]
                if header.sequence != 0:
                    findings.add(
                        Severity.WARNING,
                        RULE,
                        f"{state.source} → {state.destination}: the first HELLO seen of a session"
                        f" has sequence number {header.sequence}, not 0 (D-RSP-12): the capture"
                        " missed the ones before it, or they were not numbered from 0",
                        frame,
                        time,
                        number,
                    )
            else:
                hello[2] += 1
            self._last_hello[state.source] = key
            state.hellos = True
        elif kind is _WELCOME and isinstance(body, Welcome):
            key = (state.destination, body.client_nonce)
            hello = self._hellos.get(key)
            session = self.sessions.get(header.session_id)
            if session is None:
                session = _Session(header.session_id, state.destination, state.source, header, time)
                self.sessions[header.session_id] = session
                if hello is not None:
                    session.handshake = time - hello[0]
                    session.hello = hello
                    session.periods.append(hello[1])
                    session.first = hello[0]
                if not session.periods or session.periods[-1] != body.period_ms:
                    session.periods.append(body.period_ms)
                if header.sequence != 0:
                    findings.add(
                        Severity.WARNING,
                        RULE,
                        f"{state.source} → {state.destination}: the robot's first packet seen of"
                        f" session {header.session_id:012x}, WELCOME, has sequence number"
                        f" {header.sequence}, not 0",
                        frame,
                        time,
                        number,
                    )
        elif kind is _REFUSED and isinstance(body, Refused):
            findings.add(
                Severity.NOTE,
                "R-RSP-20",
                f"{state.source} refused {state.destination}'s HELLO: {body.reason.name}",
                frame,
                time,
                number,
            )
        elif kind is _BYE and isinstance(body, Bye):
            session = self.sessions.get(header.session_id)
            if session is not None and session.ended is None:
                who = "robot" if state.source == session.robot else "local system"
                session.ended = f"{body.reason.name} by the {who}"
        elif kind is _PERIOD and isinstance(body, Period):
            session = self.sessions.get(header.session_id)
            if session is not None and (
                not session.periods or session.periods[-1] != body.period_ms
            ):
                session.periods.append(body.period_ms)

    def _occurrences(self, header: Header, body: MapBody, time: float) -> None:
        """D-RSP-17: reliable occurrences and their ACKs, by (device, ID)."""
        session = self.sessions.get(header.session_id)
        if session is None:
            return
        kinds = self.kinds
        if header.type is _ACK:
            for item in body.items:
                if item.id is None:
                    continue
                key = (item.device, item.id)
                sent = session.occurrences.get(key)
                if sent is not None and key not in session.acked:
                    session.acked.add(key)
                    session.ack_times.append(time - sent[0])
            return
        for item in body.items:
            if item.id is None or kinds[item.device] not in _RELIABLE:
                continue
            key = (item.device, item.id)
            sent = session.occurrences.get(key)
            if sent is None:
                session.occurrences[key] = [time, 1.0]
            elif kinds[item.device] is not _COMMAND:
                # A command rides every DOWNLINK until its ACK: only memory commands and memory
                # events are sent again, after the retransmission timeout (or when their ACK
                # was lost after the capture saw it).
                sent[1] += 1

    # -- the analysis ----------------------------------------------------------------------------

    def reports(self) -> list[RspSessionReport]:
        out = []
        lasts: dict[str, float] = {}
        for stream in self.ctx.streams:
            if stream.protocol == RSP:
                lasts[stream.session] = max(lasts.get(stream.session, 0.0), stream.last)
        for session in self.sessions.values():
            sends = [int(sent[1]) for sent in session.occurrences.values()]
            times = session.ack_times
            out.append(
                RspSessionReport(
                    f"{session.id:012x}",
                    session.local,
                    session.robot,
                    session.model_id,
                    session.encryption.name,
                    tuple(session.periods),
                    session.handshake,
                    session.hello[2] if session.hello is not None else 0,
                    session.ended,
                    len(sends),
                    sum(1 for n in sends if n > 1),
                    sum(n - 1 for n in sends),
                    len(session.acked),
                    (min(times), statistics.median(times), max(times)) if times else None,
                    session.first,
                    max(session.last, lasts.get(f"{session.id:012x}", 0.0)),
                )
            )
        return out
