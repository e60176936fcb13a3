"""The flow table: each frame to its conversation, each conversation to its protocol's decoder.

Which protocol a flow carries is `classify.Classifier`'s to say (the scapy layers ask it too): a
UDP flow is classified once, by its first datagram, and its decoder and state kept in the table; a
TCP connection is a control connection, not ours, or held until its first bytes tell.
"""

from __future__ import annotations

import struct
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from rcmlconf.dissect.classify import FlowKey, Pending, reverse
from rcmlconf.dissect.context import Context, Options
from rcmlconf.dissect.control import ControlConnection
from rcmlconf.dissect.control_results import ControlReport
from rcmlconf.dissect.datastream import DataFlow, DataStreamDecoder, HeartbeatReport, stream_label
from rcmlconf.dissect.records import (
    RCTP,
    RCTP_DATA,
    RSP,
    Endpoints,
    Finding,
    Record,
    Severity,
)
from rcmlconf.dissect.rsp import RspDecoder, RspFlow, RspSessionReport
from rcmlconf.dissect.streams import Stream, StreamReport
from rcmlconf.pcap.addresses import endpoint_text
from rcmlconf.pcap.frames import LINKTYPE_IPV4, LINKTYPE_RAW, TCP, UDP, FrameDecoder
from rcmlconf.pcap.reader import Capture
from rcmlconf.pcap.records import CaptureError, FrameError

#: Frame problems kept; the rest are counted.
PROBLEMS_KEPT = 100
#: Of an IPv4 header and the UDP header after it: version and length, total length, fragment
#: field, protocol, the addresses and ports (12 bytes: a UDP flow's key), UDP length.
_IPV4_UDP_HEAD = struct.Struct("!BxH2xHxB2x12sH")
_RAW_IPV4 = frozenset({LINKTYPE_RAW, LINKTYPE_IPV4})
_KEY = struct.Struct("!4s4sHH")


@dataclass(frozen=True, slots=True)
class CaptureReport:
    name: str
    format: str
    frames: int
    first: float | None
    last: float | None
    #: Messages decoded, per protocol.
    messages: dict[str, int]
    #: Frames of no protocol of ours (no IP, no TCP or UDP, traffic of other protocols).
    other: int
    #: Frames whose headers could not be read: (frame, file offset, reason); and how many more.
    problems: tuple[tuple[int, int, str], ...]
    problems_left_out: int
    #: Why the file could not be read to its end, and where.
    error: tuple[int, str] | None


@dataclass(frozen=True, slots=True)
class Analysis:
    capture: CaptureReport
    control: tuple[ControlReport, ...]
    streams: tuple[StreamReport, ...]
    heartbeats: tuple[HeartbeatReport, ...]
    rsp_sessions: tuple[RspSessionReport, ...]
    findings: tuple[Finding, ...]
    #: (severity, rule) -> findings left out of `findings` past the first ones.
    left_out: dict[tuple[Severity, str], int] = field(default_factory=dict)

    @property
    def errors(self) -> int:
        kept = sum(1 for f in self.findings if f.severity is Severity.ERROR)
        return kept + sum(n for (s, _), n in self.left_out.items() if s is Severity.ERROR)


#: A UDP flow's entry: (handler, endpoints, state), or no handler for a flow of none of ours.
_UdpEntry = tuple[Callable[..., None] | None, Endpoints | None, Any]
_IGNORED: _UdpEntry = (None, None, None)


#: A segment of a connection held by `Pending`: (side, time, frame, sequence number, flags,
#: payload, its offset in the file).
_Held = tuple[int, float, int, int, int, bytes, int]


class Dissector:
    """Dissect captures: each message to `emit` as it is decoded, the analysis at the end."""

    def __init__(self, options: Options, emit: Callable[[Record], None]) -> None:
        self.options = options
        self.ctx = Context(options, emit)
        self.ctx.learned = self._forget_ignored
        self._flows = self.ctx.flows
        self._udp: dict[FlowKey, _UdpEntry] = {}
        #: The same entries, by the 12 bytes of an IPv4 header's addresses and UDP's ports.
        self._udp4: dict[bytes, _UdpEntry] = {}
        self._tcp: dict[FlowKey, tuple[Any, int]] = {}
        self._connections: list[ControlConnection] = []
        self._datastream = DataStreamDecoder(self.ctx)
        self._rsp = RspDecoder(self.ctx)
        self._names: dict[tuple[bytes, int], str] = {}
        self.frames = 0
        self.other = 0
        self.first: float | None = None
        self.last: float | None = None
        self._problems: list[tuple[int, int, str]] = []
        self._problems_left_out = 0
        self.error: tuple[int, str] | None = None

    @property
    def streams(self) -> list[Stream]:
        """Every stream found so far, with its time series when `Options.series` is set."""
        return self.ctx.streams

    # -- the run ---------------------------------------------------------------------------------

    def run(self, capture: Capture) -> Analysis:
        """Dissect every record; a file whose structure breaks is read up to there."""
        try:
            self._records(capture)
        except CaptureError as error:
            self.error = (error.offset, error.reason)
        return self.finish(capture.name, capture.format)

    def _records(self, capture: Capture) -> None:
        data = capture.data
        decoder = FrameDecoder()
        decode = decoder.decode
        head = _IPV4_UDP_HEAD.unpack_from
        raw_ipv4 = _RAW_IPV4
        udp = self._udp
        fast = self._udp4
        classify = self._classify_udp
        frame = self.frames
        time = 0.0
        first = self.first
        other = 0
        try:
            for time, linktype, start, end, length in capture.records():
                frame += 1
                if first is None:
                    first = time
                # The common case inline (FrameDecoder.decode's first branch): raw IPv4 with a
                # 20-byte header, UDP, no fragment, nothing cut; its flow found by the header's
                # addresses and ports as they are, 12 bytes.
                if linktype in raw_ipv4 and end - start >= 28:
                    first_byte, total, fragment, protocol, key12, size = head(data, start)
                    stop = start + 20 + size
                    if (
                        first_byte == 0x45
                        and protocol == UDP
                        and not fragment & 0x3FFF
                        and 8 <= size <= total - 20
                        and stop <= end
                        and length <= end - start
                    ):
                        entry = fast.get(key12)
                        payload = data[start + 28 : stop]
                        if entry is None:
                            entry = fast[key12] = classify(_key(key12), payload)
                        handler, flow, state = entry
                        if handler is None:
                            other += 1
                        else:
                            handler(flow, state, time, frame, payload, start + 28)
                        continue
                try:
                    segment = decode(data, start, end, linktype, length)
                except FrameError as error:
                    self._problem(frame, error.offset, error.reason)
                    continue
                if segment is None:
                    continue
                protocol, source, sport, destination, dport, payload, where, seq, flags, cut = (
                    segment
                )
                if protocol == UDP:
                    key = (source, sport, destination, dport)
                    entry = udp.get(key)
                    if entry is None:
                        entry = classify(key, payload)
                    handler = entry[0]
                    if handler is None:
                        other += 1
                    elif cut:
                        self._problem(frame, end, "datagram cut short by the snap length")
                    else:
                        handler(entry[1], entry[2], time, frame, payload, where)
                elif protocol == TCP:
                    self._segment(
                        time, frame, source, sport, destination, dport, payload, where, seq, flags
                    )
        finally:
            self.frames = frame
            self.first = first
            self.other += decoder.skipped + other
            if frame:
                self.last = time

    def finish(self, name: str = "<capture>", form: str = "pcap") -> Analysis:
        """The analysis of everything dissected so far."""
        ctx = self.ctx
        for connection in self._connections:
            connection.end()
        self._datastream.end(self.last if self.last is not None else 0.0)
        counts = ctx.by_protocol
        counts[RCTP_DATA] = self._datastream.malformed
        counts[RSP] = self._rsp.malformed
        for stream in ctx.streams:
            counts[stream.protocol] += stream.packets
            if stream.protocol == RCTP_DATA:
                session = ctx.data_sessions.get(int(stream.session, 16))
                if session is not None:
                    stream.label = stream_label(session)
        capture = CaptureReport(
            name,
            form,
            self.frames,
            self.first,
            self.last,
            {p: ctx.by_protocol[p] for p in (RCTP, RCTP_DATA, RSP) if ctx.by_protocol[p]},
            self.other,
            tuple(self._problems),
            self._problems_left_out,
            self.error,
        )
        return Analysis(
            capture,
            tuple(c.report() for c in self._connections),
            tuple(s.report() for s in ctx.streams),
            tuple(self._datastream.heartbeats()),
            tuple(self._rsp.reports()),
            tuple(ctx.findings.items),
            dict(ctx.findings.left_out),
        )

    def _problem(self, frame: int, offset: int, reason: str) -> None:
        if len(self._problems) < PROBLEMS_KEPT:
            self._problems.append((frame, offset, reason))
        else:
            self._problems_left_out += 1

    def _name(self, address: bytes, port: int) -> str:
        key = (address, port)
        name = self._names.get(key)
        if name is None:
            name = self._names[key] = endpoint_text(address, port)
        return name

    # -- UDP -------------------------------------------------------------------------------------

    def _classify_udp(self, key: FlowKey, payload: bytes) -> _UdpEntry:
        protocol = self._flows.udp(key, payload)
        if protocol is None:
            entry = _IGNORED
        else:
            source, sport, destination, dport = key
            src, dst = self._name(source, sport), self._name(destination, dport)
            endpoints = Endpoints(src, dst, protocol)
            if protocol == RSP:
                entry = (self._rsp.datagram, endpoints, RspFlow(src, dst))
            else:
                entry = (self._datastream.datagram, endpoints, DataFlow(src, dst, source, sport))
        self._udp[key] = entry
        return entry

    def _forget_ignored(self) -> None:
        """SETUP named new data-stream ports: flows not recognised yet are looked at again."""
        for key in [k for k, entry in self._udp.items() if entry[0] is None]:
            del self._udp[key]
        for key12 in [k for k, entry in self._udp4.items() if entry[0] is None]:
            del self._udp4[key12]

    # -- TCP -------------------------------------------------------------------------------------

    def _segment(
        self,
        time: float,
        frame: int,
        source: bytes,
        sport: int,
        destination: bytes,
        dport: int,
        payload: bytes,
        where: int,
        seq: int,
        flags: int,
    ) -> None:
        key = (source, sport, destination, dport)
        found = self._tcp.get(key)
        if found is None:
            found = self._open_tcp(key)
        connection, index = found
        if connection is None:
            self.other += 1
            return
        if isinstance(connection, Pending):
            held: _Held = (index, time, frame, seq, flags, payload, where)
            decided = self._flows.look(connection, index, held, payload)
            if decided is None:
                return
            segments: list[_Held] = connection.segments
            if decided:
                real = self._control(connection.first)
                for side, at, number, sequence, bits, data, located in segments:
                    real.segment(side, at, number, sequence, bits, data, located)
            else:
                self._tcp[key] = self._tcp[reverse(key)] = (None, 0)
                self.other += len(segments)
            return
        connection.segment(index, time, frame, seq, flags, payload, where)

    def _open_tcp(self, key: FlowKey) -> tuple[Any, int]:
        rctp = self._flows.tcp(key)
        if rctp:
            self._control(key)
        elif rctp is None:
            pending: Pending[_Held] = Pending(key)
            self._tcp[key] = (pending, 0)
            self._tcp[reverse(key)] = (pending, 1)
        else:
            self._tcp[key] = self._tcp[reverse(key)] = (None, 0)
        return self._tcp[key]

    def _control(self, key: FlowKey) -> ControlConnection:
        """A control connection whose side 0 sent from `key`'s source."""
        source, sport, destination, dport = key
        connection = ControlConnection.open(
            self.ctx,
            (source, sport, self._name(source, sport)),
            (destination, dport, self._name(destination, dport)),
            self._flows.tcp_ports,
        )
        self._connections.append(connection)
        self._tcp[key] = (connection, 0)
        self._tcp[reverse(key)] = (connection, 1)
        return connection


def _key(key12: bytes) -> FlowKey:
    """(source, source port, destination, destination port) of IPv4's addresses and UDP's ports."""
    source, destination, sport, dport = _KEY.unpack(key12)
    return source, sport, destination, dport
