"""The flow table: each frame to its conversation, each conversation to its protocol's decoder.

A UDP flow (one direction: source and destination address and port) is classified once, by its
first datagram: `--decode-as` ports first, then the data-stream ports SETUP named (D-RCTP-18, as
Wireshark follows RTSP's SETUP to its RTP ports), then the default ports (UDP 7340 RSP, D-RSP-9;
UDP 7330 the data stream, which the reference server serves on its TCP port's number), then, with
heuristics on, the datagram itself: a valid data-stream packet (D-RCTP-19) or a valid RSP header
(D-RSP-10). A TCP connection is RCTP when either port is 7330 (D-RCTP-2), a `--decode-as` port or
a server endpoint already seen speaking RCTP, or, with heuristics on, when its first bytes are an
RCTP start line.
"""

from __future__ import annotations

import re
import struct
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from rcmlconf.dissect.context import Context, Options
from rcmlconf.dissect.control import ControlConnection, ControlReport
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
from rcmlconf.errors import ProtocolError
from rcmlconf.pcap.reader import (
    LINKTYPE_IPV4,
    LINKTYPE_RAW,
    TCP,
    UDP,
    Capture,
    CaptureError,
    FrameDecoder,
    FrameError,
    endpoint_text,
)
from rcmlconf.rctp.datastream.packets import pull_packet
from rcmlconf.rctp.messages import METHODS
from rcmlconf.rsp.codec.header import ANY

#: D-RCTP-2: RCTP's TCP port; D-RSP-9: RSP's UDP port; the reference server's data stream uses
#: its TCP port's number (D-RCTP-28 leaves it to the server).
DEFAULT_TCP = {7330: RCTP}
DEFAULT_UDP = {7340: RSP, 7330: RCTP_DATA}
#: Frame problems kept; the rest are counted.
PROBLEMS_KEPT = 100
_START = re.compile(
    rb"RCTP/[0-9]|(?:" + b"|".join(m.encode() for m in METHODS) + rb") |"
    rb"[!#$%&'*+\-.^_`|~0-9A-Za-z]+ [!-~]+ RCTP/[0-9]"
)
#: Of an IPv4 header and the UDP header after it: version and length, total length, fragment
#: field, protocol, UDP length.
_IPV4_UDP_HEAD = struct.Struct("!BxH2xHxB14xH")
_KEY = struct.Struct("!4s4sHH")
#: Bytes of a TCP connection's first payloads looked at to recognise RCTP.
_LOOK = 16


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


class _PendingTcp:
    """A TCP connection not yet recognised: its segments, to be replayed once it is."""

    __slots__ = ("looked", "segments")

    def __init__(self) -> None:
        self.segments: list[tuple[int, float, int, int, int, bytes, int]] = []
        self.looked = [b"", b""]


class Dissector:
    """Dissect captures: each message to `emit` as it is decoded, the analysis at the end."""

    def __init__(self, options: Options, emit: Callable[[Record], None]) -> None:
        self.options = options
        self.ctx = Context(options, emit)
        self.ctx.learned = self._forget_ignored
        tcp_ports = dict(DEFAULT_TCP)
        udp_ports = dict(DEFAULT_UDP)
        for protocol, port in options.decode_as:
            if protocol == RCTP:
                tcp_ports[port] = protocol
            else:
                udp_ports[port] = protocol
        self._tcp_ports = frozenset(tcp_ports)
        self._udp_ports = udp_ports
        self._decode_as_udp = {port: p for p, port in options.decode_as if p != RCTP}
        self._udp: dict[tuple[bytes, int, bytes, int], _UdpEntry] = {}
        #: The same entries, by the 12 bytes of an IPv4 header's addresses and UDP's ports.
        self._udp4: dict[bytes, _UdpEntry] = {}
        self._tcp: dict[tuple[bytes, int, bytes, int], tuple[Any, int]] = {}
        self._connections: list[ControlConnection] = []
        #: Server endpoints seen speaking RCTP: later connections to them are RCTP too.
        self._rctp_servers: set[tuple[bytes, int]] = set()
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
                if (linktype in (LINKTYPE_RAW, LINKTYPE_IPV4)) and end - start >= 28:
                    first_byte, total, fragment, protocol, size = head(data, start)
                    stop = start + 20 + size
                    if (
                        first_byte == 0x45
                        and protocol == UDP
                        and not fragment & 0x3FFF
                        and 8 <= size <= total - 20
                        and stop <= end
                        and length <= end - start
                    ):
                        key12 = data[start + 12 : start + 24]
                        entry = fast.get(key12)
                        payload = data[start + 28 : stop]
                        if entry is None:
                            entry = fast[key12] = classify(_key(key12), payload)
                        handler = entry[0]
                        if handler is None:
                            other += 1
                        else:
                            handler(entry[1], entry[2], time, frame, payload, start + 28)
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

    def _classify_udp(self, key: tuple[bytes, int, bytes, int], payload: bytes) -> _UdpEntry:
        source, sport, destination, dport = key
        protocol = self._udp_protocol(source, sport, destination, dport, payload)
        if protocol is None:
            entry = _IGNORED
        else:
            src, dst = self._name(source, sport), self._name(destination, dport)
            endpoints = Endpoints(src, dst, protocol)
            if protocol == RSP:
                entry = (self._rsp.datagram, endpoints, RspFlow(src, dst))
            else:
                entry = (self._datastream.datagram, endpoints, DataFlow(src, dst, source, sport))
        self._udp[key] = entry
        return entry

    def _udp_protocol(
        self, source: bytes, sport: int, destination: bytes, dport: int, payload: bytes
    ) -> str | None:
        chosen = self._decode_as_udp
        if dport in chosen:
            return chosen[dport]
        if sport in chosen:
            return chosen[sport]
        endpoints = self.ctx.data_endpoints
        if (destination, dport) in endpoints or (source, sport) in endpoints:
            return RCTP_DATA
        ports = self._udp_ports
        if dport in ports:
            return ports[dport]
        if sport in ports:
            return ports[sport]
        if not self.options.heuristics or not payload:
            return None
        if payload[0] == 2:
            try:
                pull_packet(payload)
            except ProtocolError:
                return None
            return RCTP_DATA
        if payload[0] == 1:
            try:
                ANY.pull(payload)
            except ProtocolError:
                return None
            return RSP
        return None

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
            found = self._open_tcp(key, payload)
        connection, index = found
        if connection is None:
            self.other += 1
            return
        if isinstance(connection, _PendingTcp):
            connection.segments.append((index, time, frame, seq, flags, payload, where))
            connection.looked[index] += payload
            decided = self._recognise(connection.looked, len(connection.segments))
            if decided is None:
                return
            segments = connection.segments
            if decided:
                first = key if index == 0 else _reverse(key)
                real = self._control(first)
                for side, data in enumerate(connection.looked):
                    if _START.match(data) and not data.startswith(b"RCTP/"):
                        # The side that sent a request line is a client: its peer is a server.
                        server = first[2:] if side == 0 else first[:2]
                        self._rctp_servers.add((server[0], server[1]))
                for side, at, number, sequence, bits, data, where in segments:
                    real.segment(side, at, number, sequence, bits, data, where)
            else:
                self._tcp[key] = self._tcp[_reverse(key)] = (None, 0)
                self.other += len(segments)
            return
        connection.segment(index, time, frame, seq, flags, payload, where)

    def _open_tcp(self, key: tuple[bytes, int, bytes, int], payload: bytes) -> tuple[Any, int]:
        source, sport, destination, dport = key
        ports = self._tcp_ports
        servers = self._rctp_servers
        if (
            dport in ports
            or sport in ports
            or (destination, dport) in servers
            or (source, sport) in servers
        ):
            connection: Any = self._control(key)
        elif self.options.heuristics:
            connection = _PendingTcp()
            self._tcp[key] = (connection, 0)
            self._tcp[_reverse(key)] = (connection, 1)
        else:
            self._tcp[key] = self._tcp[_reverse(key)] = (None, 0)
        return self._tcp[key]

    def _control(self, key: tuple[bytes, int, bytes, int]) -> ControlConnection:
        """A control connection whose side 0 sent from `key`'s source."""
        source, sport, destination, dport = key
        connection = ControlConnection.open(
            self.ctx,
            (source, sport, self._name(source, sport)),
            (destination, dport, self._name(destination, dport)),
            self._tcp_ports,
        )
        self._connections.append(connection)
        self._tcp[key] = (connection, 0)
        self._tcp[_reverse(key)] = (connection, 1)
        if dport in self._tcp_ports:
            self._rctp_servers.add((destination, dport))
        elif sport in self._tcp_ports:
            self._rctp_servers.add((source, sport))
        return connection

    @staticmethod
    def _recognise(looked: list[bytes], segments: int) -> bool | None:
        """Whether the first bytes of a connection are RCTP's; None to wait for more."""
        for data in looked:
            if _START.match(data):
                return True
        if any(len(data) >= _LOOK or b"\n" in data for data in looked) or segments > 32:
            return False
        return None


def _key(key12: bytes) -> tuple[bytes, int, bytes, int]:
    """(source, source port, destination, destination port) of IPv4's addresses and UDP's ports."""
    source, destination, sport, dport = _KEY.unpack(key12)
    return source, sport, destination, dport


def _reverse(key: tuple[bytes, int, bytes, int]) -> tuple[bytes, int, bytes, int]:
    return key[2], key[3], key[0], key[1]
