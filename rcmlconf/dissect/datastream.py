"""The RCTP/2.0 data stream seen from the wire (specs/rctp-2.0.md §6).

Each datagram is decoded by the core's `pull_packet` (D-RCTP-19), which lets only
`ProtocolError` escape, with the offset and rule of a broken packet. A stream is one sender's
packets of one session (its tag): sequence numbers by the rules of D-RCTP-21 (`streams.Stream`,
with the core's `SequenceTracker`), timestamps into RFC 3550's jitter. Heartbeats
are paired by request id, each pair a round trip and a clock sample (`ClockSample.from_times`,
NTP's filter in `ClockEstimator`, D-RCTP-24); the ACK's arrival stands for T4, so the offset is
that of the capturing host's clock (the client's, when the capture was made there). With the RCML
of the robot, DATA payloads are decoded as the values of the stream access SETUP named for their
stream id (D-RCTP-20).
"""

from __future__ import annotations

import statistics
from dataclasses import dataclass
from typing import Any

from rcmlconf.dissect.context import Context, DataSession
from rcmlconf.dissect.records import RCTP_DATA, Malformed, Record, Severity, make_record
from rcmlconf.dissect.streams import Stream
from rcmlconf.errors import ProtocolError
from rcmlconf.rcml.model import AccessNode, DataNode
from rcmlconf.rctp.bodies import ValuesCodec
from rcmlconf.rctp.datastream.clock import (
    ClockEstimate,
    ClockEstimator,
    ClockSample,
    ntp_from_unix,
)
from rcmlconf.rctp.datastream.flow import Direction, HeartbeatAck, HeartbeatRequest, Message, Nack
from rcmlconf.rctp.datastream.packets import (
    DataPayload,
    FlowPayload,
    MalformedFlowPayload,
    Packet,
    UnknownPayload,
    body_offsets,
    pull_packet,
)
from rcmlconf.values import Value

_KIND = {
    DataPayload: "DATA",
    FlowPayload: "FLOW",
    MalformedFlowPayload: "FLOW",
    UnknownPayload: "UNKNOWN",
}
_record = tuple.__new__
_NTP_SECOND = 2.0**-32


#: D-RCTP-22: a request is sent five times 250 ms apart before its requester gives up.
FLOW_PATIENCE = 1.5
RULE = "R-RCTP-39"


@dataclass(frozen=True, slots=True)
class HeartbeatReport:
    """The heartbeats of one requester in one data stream (D-RCTP-24)."""

    tag: str
    requester: str
    answerer: str
    requests: int
    answered: int
    #: Round trips as the capture saw them (request to ACK), seconds: min, median, max.
    round_trip: tuple[float, float, float] | None
    #: NTP's estimate of the answerer's clock minus the capturing host's.
    clock: ClockEstimate | None


@dataclass(frozen=True, slots=True)
class DataValues:
    """`Record.extra` of a data-stream packet decoded with the RCML: one entry per payload,
    the values of a DATA payload (or None: not a DATA payload, or no RCML access for it)."""

    values: tuple[tuple[str, str, dict[str, Value]] | None, ...]


class _Heartbeats:
    __slots__ = ("answerer", "estimator", "requests", "round_trips", "tag")

    def __init__(self, tag: int, answerer: str, precision: float) -> None:
        self.tag = tag
        self.answerer = answerer
        self.requests = 0
        self.round_trips: list[float] = []
        self.estimator = ClockEstimator(precision)


class DataFlow:
    """What a data-stream direction keeps: its streams by tag, the last one at hand."""

    __slots__ = ("address", "destination", "port", "server", "source", "stream", "streams", "tag")

    def __init__(self, source: str, destination: str, address: bytes, port: int) -> None:
        self.source = source
        self.destination = destination
        self.address = address
        self.port = port
        self.tag = -1
        #: The stream of `tag`: set with it, before it is read.
        self.stream: Stream = None  # type: ignore[assignment]
        self.streams: dict[int, Stream] = {}
        #: Whether the robot sends this direction (None: no SETUP seen for the tag).
        self.server: bool | None = None


class DataStreamDecoder:
    def __init__(self, ctx: Context) -> None:
        self.ctx = ctx
        #: (tag, requester, request id) -> (time, frame, message number, T1 or None).
        self._requests: dict[tuple[int, str, int], tuple[float, int, int, int | None]] = {}
        self._heartbeats: dict[tuple[int, str], _Heartbeats] = {}
        self._codecs: dict[tuple[int, int, bool], ValuesCodec[DataNode] | None] = {}
        self._rcml = ctx.options.rcml is not None
        #: Datagrams that could not be read (the others are counted by their streams).
        self.malformed = 0

    def datagram(
        self, flow: Any, state: DataFlow, time: float, frame: int, payload: bytes, where: int
    ) -> None:
        ctx = self.ctx
        number = ctx.count = ctx.count + 1
        try:
            packet = pull_packet(payload)
        except ProtocolError as error:
            self._malformed(flow, time, frame, number, error, where)
            return
        sequence, tag, timestamp, payloads = packet
        stream = state.stream if tag == state.tag else self._stream(state, tag, frame, time, number)
        # Seconds since the NTP era's start: the jitter and the plot take only differences.
        stream.see(time, sequence, timestamp * _NTP_SECOND, len(payload))
        extra = None
        if len(payloads) == 1 and type(payloads[0]) is DataPayload:
            kind = "DATA"
            if self._rcml:
                extra = self._values(state, packet, frame, time, number, where)
        else:
            kind = "+".join([_KIND[type(p)] for p in payloads])
            self._payloads(state, packet, time, frame, number, where)
            if self._rcml and "DATA" in kind:
                extra = self._values(state, packet, frame, time, number, where)
        ctx.emit(_record(Record, (number, frame, time, flow, kind, sequence, packet, None, extra)))

    def _malformed(
        self, flow: Any, time: float, frame: int, number: int, error: ProtocolError, where: int
    ) -> None:
        self.malformed += 1
        rule = error.rule or RULE
        located = where + error.offset if where >= 0 else None
        malformed = Malformed(error.reason, error.offset, rule, located)
        self.ctx.findings.add(
            Severity.ERROR,
            rule,
            f"{flow.source} → {flow.destination}: a data-stream packet that cannot be read:"
            f" {error.reason} (byte {error.offset}); a receiver drops it (R-RCTP-42)",
            frame,
            time,
            number,
            located,
        )
        self.ctx.emit(make_record(number, frame, time, flow, "malformed", None, None, malformed))

    # -- streams ---------------------------------------------------------------------------------

    def _stream(self, state: DataFlow, tag: int, frame: int, time: float, number: int) -> Stream:
        ctx = self.ctx
        stream = state.streams.get(tag)
        if stream is None:
            stream = ctx.stream(
                RCTP_DATA, state.source, state.destination, f"{tag:08x}", "R-RCTP-41"
            )
            state.streams[tag] = stream
            self._check_ends(state, tag, stream, frame, time, number)
        state.tag = tag
        state.stream = stream
        return stream

    def _check_ends(
        self, state: DataFlow, tag: int, stream: Stream, frame: int, time: float, number: int
    ) -> None:
        """D-RCTP-28, R-RCTP-56: the robot sends from its server_port to the client_port of the
        latest SETUP; a client's packets come from that port, with the session's tag."""
        ctx = self.ctx
        session = ctx.data_sessions.get(tag)
        where = f"{state.source} → {state.destination}"
        if session is None:
            known = ctx.data_endpoints.get((state.address, state.port))
            if known is not None:
                ctx.findings.add(
                    Severity.WARNING,
                    "R-RCTP-42",
                    f"{where}: tag {tag:08x} is not the session's ({known.tag:08x}): a receiver"
                    " drops these packets",
                    frame,
                    time,
                    number,
                )
            return
        stream.label = stream_label(session)
        server = state.address == session.server_address and state.port == session.server_port
        to_client = state.destination.endswith(f":{session.client_port}")
        state.server = server or (to_client and state.address == session.server_address)
        if state.server and not server:
            ctx.findings.add(
                Severity.ERROR,
                "R-RCTP-56",
                f"{where}: the robot sends the data stream from port {state.port}, not its"
                f" server_port {session.server_port}",
                frame,
                time,
                number,
            )
        elif not state.server and state.port != session.client_port:
            ctx.findings.add(
                Severity.WARNING,
                "R-RCTP-42",
                f"{where}: packets of tag {tag:08x} from port {state.port}, not the client_port"
                f" {session.client_port} of the latest SETUP: a receiver drops them",
                frame,
                time,
                number,
            )

    # -- payloads ------------------------------------------------------------------------------

    def _payloads(
        self, state: DataFlow, packet: Packet, time: float, frame: int, number: int, where: int
    ) -> None:
        for payload in packet.payloads:
            kind = type(payload)
            if kind is FlowPayload:
                assert isinstance(payload, FlowPayload)
                self._flow(state, packet.tag, payload, time, frame, number)
            elif kind is MalformedFlowPayload:
                assert isinstance(payload, MalformedFlowPayload)
                answer = "owed a NACK 5" if payload.answer is not None else "ignored"
                self.ctx.findings.add(
                    Severity.ERROR,
                    "R-RCTP-52",
                    f"{state.source} → {state.destination}: a FLOW body that breaks its layout:"
                    f" {payload.reason} (byte {payload.offset}); {answer} (R-RCTP-53)",
                    frame,
                    time,
                    number,
                    where + payload.offset if where >= 0 else None,
                )

    def _flow(
        self, state: DataFlow, tag: int, payload: FlowPayload, time: float, frame: int, number: int
    ) -> None:
        flow = payload.flow
        requests = self._requests
        if flow.message == Message.REQUEST:
            key = (tag, state.source, flow.request_id)
            if key not in requests:
                t1 = flow.t1 if isinstance(flow, HeartbeatRequest) else None
                requests[key] = (time, frame, number, t1)
            if isinstance(flow, HeartbeatRequest):
                self._heartbeat(tag, state.source, state.destination).requests += 1
            return
        key = (tag, state.destination, flow.request_id)
        asked = requests.pop(key, None)
        if asked is None:
            return  # a repeated answer, or one to a request the capture missed
        sent, _, _, t1 = asked
        if isinstance(flow, HeartbeatAck):
            heartbeats = self._heartbeat(tag, state.destination, state.source)
            if t1 is not None and flow.t1 != t1:
                self.ctx.findings.add(
                    Severity.ERROR,
                    "R-RCTP-48",
                    f"{state.source} → {state.destination}: heartbeat ACK {flow.request_id}"
                    f" echoes T1 {flow.t1:016x}, not the request's {t1:016x}",
                    frame,
                    time,
                    number,
                )
                return
            heartbeats.round_trips.append(time - sent)
            heartbeats.estimator.add(
                ClockSample.from_times(flow.t1, flow.t2, flow.t3, ntp_from_unix(time))
            )
        elif isinstance(flow, Nack):
            pass  # an answer: the request is settled (R-RCTP-46)

    def _heartbeat(self, tag: int, requester: str, answerer: str) -> _Heartbeats:
        found = self._heartbeats.get((tag, requester))
        if found is None:
            session = self.ctx.data_sessions.get(tag)
            precision = session.precision if session is not None else 0.0
            found = self._heartbeats[(tag, requester)] = _Heartbeats(tag, answerer, precision)
        return found

    # -- DATA values with the RCML ---------------------------------------------------------------

    def _values(
        self, state: DataFlow, packet: Packet, frame: int, time: float, number: int, where: int
    ) -> DataValues | None:
        session = self.ctx.data_sessions.get(packet.tag)
        if session is None or state.server is None:
            return None
        shown: list[tuple[str, str, dict[str, Value]] | None] = []
        offsets = body_offsets(packet)
        for payload, offset in zip(packet.payloads, offsets, strict=True):
            if type(payload) is not DataPayload:
                shown.append(None)
                continue
            assert isinstance(payload, DataPayload)
            codec = self._codec(session, payload.stream, state.server)
            if codec is None:
                shown.append(None)
                continue
            try:
                values = codec.decode(payload.body, offset)
            except ProtocolError as error:
                self.ctx.findings.add(
                    Severity.ERROR,
                    error.rule or "R-RCTP-40",
                    f"{state.source} → {state.destination}: DATA of stream {payload.stream}:"
                    f" {error.reason} (byte {error.offset}); a receiver ignores it (R-RCTP-58)",
                    frame,
                    time,
                    number,
                    where + error.offset if where >= 0 else None,
                )
                shown.append(None)
                continue
            shown.append((codec.where, "read" if state.server else "write", values))
        return DataValues(tuple(shown))

    def _codec(
        self, session: DataSession, stream: int, server: bool
    ) -> ValuesCodec[DataNode] | None:
        key = (session.tag, stream, server)
        if key in self._codecs:
            return self._codecs[key]
        codec = None
        rcml = self.ctx.options.rcml
        found = session.streams.get(stream)
        if rcml is not None and found is not None:
            access = rcml.node(found[0])
            if isinstance(access, AccessNode):
                from rcmlconf.rctp.datastream.values import stream_codec

                codec = stream_codec(access, Direction.READ if server else Direction.WRITE)
        self._codecs[key] = codec
        return codec

    # -- the analysis ----------------------------------------------------------------------------

    def end(self, last_time: float) -> None:
        """The capture is over at `last_time`: requests never answered."""
        for (tag, requester, request_id), (sent, frame, number, _) in self._requests.items():
            if last_time - sent < FLOW_PATIENCE:
                continue  # the capture ended before the requester would have given up
            self.ctx.findings.add(
                Severity.WARNING,
                "R-RCTP-46",
                f"FLOW request {request_id} of {requester} (tag {tag:08x}) was never answered in"
                " the capture",
                frame,
                sent,
                number,
            )

    def heartbeats(self) -> list[HeartbeatReport]:
        reports = []
        for (tag, requester), beats in self._heartbeats.items():
            trips = beats.round_trips
            reports.append(
                HeartbeatReport(
                    f"{tag:08x}",
                    requester,
                    beats.answerer,
                    beats.requests,
                    len(trips),
                    (min(trips), statistics.median(trips), max(trips)) if trips else None,
                    beats.estimator.estimate,
                )
            )
        return reports


def stream_label(session: DataSession) -> str:
    """`stream 1 /drive/wheels (read)`, for the streams SETUP named."""
    parts = [
        f"stream {number} {path} ({transport.mode})"
        for number, (path, transport) in sorted(session.streams.items())
    ]
    return ", ".join(parts)
