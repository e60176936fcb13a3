"""RCTP and RSP messages of a capture, each dissected by the scapy layers: `rcmlconf dissect -V`
and `rcmlconf sniff`.

Building a scapy packet for the IP, TCP and UDP headers of every frame costs more than the
layers themselves (about 150 µs a frame against 50), so the headers are read here with `struct`
and scapy dissects the RCTP and RSP bytes only. TCP is reassembled per direction, in sequence
order, and cut into messages by `rctp.message_length` (Content-Length framing, pipelining,
R-RCTP-13). Flows are found as `rcmlconf dissect` finds them (`Dissector`): default ports,
`--decode-as`, the data-stream endpoints of SETUP's answers (D-RCTP-18), and heuristics.

`render` writes a packet as scapy's `show(dump=True)` does, without its color-theme calls per
field, which cost more than the dissection: `-V` on 10,000 packets takes about 2 s.
"""

from __future__ import annotations

import functools
import ipaddress
import os
import re
import struct
from collections.abc import Iterable, Iterator
from datetime import datetime
from typing import TYPE_CHECKING, Any, NamedTuple

from scapy.config import conf
from scapy.fields import ConditionalField
from scapy.packet import Packet
from scapy.utils import RawPcapReader

from rcmlconf.scapy_layers import rctp, rsp

if TYPE_CHECKING:
    from rcmlconf.rsp.model import RobotModel

#: The protocols, as `--decode-as` names them: RCTP's control connection (TCP) and its data stream
#: (UDP), and RSP (UDP).
RCTP, RCTP_DATA, RSP = "rctp", "rctp-data", "rsp"
PROTOCOLS = (RCTP, RCTP_DATA, RSP)
#: The default ports: TCP 7330 (D-RCTP-2); UDP 7340 for RSP (D-RSP-9) and UDP 7330 for the data
#: stream, which the reference server serves on its TCP port's number.
DEFAULT_TCP = {rctp.RCTP_PORT: RCTP}
DEFAULT_UDP = {rsp.RSP_PORT: RSP, rctp.RCTP_PORT: RCTP_DATA}
#: A message's protocol, as a summary line names it.
PROTOCOL_NAMES = {RCTP: "RCTP", RCTP_DATA: "RCTP-data", RSP: "RSP"}

Address = tuple[str, int]


class Message(NamedTuple):
    """One RCTP control message, data-stream packet or RSP packet of a capture."""

    #: The capture's record (1 for the first) that completed the message.
    frame: int
    #: Seconds since the epoch, the record's stamp.
    time: float
    #: "rctp" (control, over TCP), "rctp-data" or "rsp" (over UDP).
    protocol: str
    source: Address
    destination: Address
    #: The layer: RCTPRequest, RCTPResponse, RCTPStream or RSP; Raw for bytes that cannot be
    #: framed as the protocol (D-RCTP-10, R-RCTP-39, R-RSP-13).
    packet: Packet


def parse_decode_as(text: str) -> tuple[str, int]:
    """`PROTO=PORT` (`rctp=8000`, `rctp-data=41000`, `rsp=9000`); ValueError for anything else."""
    proto, equals, port = text.partition("=")
    proto = proto.strip().lower()
    if not equals or proto not in PROTOCOLS:
        raise ValueError(f"{text!r}: give PROTO=PORT with PROTO one of {', '.join(PROTOCOLS)}")
    if not port.strip().isdigit() or not 0 < int(port) < 65536:
        raise ValueError(f"{text!r}: the port must be 1 to 65535")
    return proto, int(port)


DecodeAs = Iterable[str | tuple[str, int]]

#: The start of an RCTP message: what makes a connection on another port RCTP (heuristics).
_START = re.compile(
    rb"RCTP/[0-9]|(?:" + b"|".join(rctp.RCTP_METHODS) + rb") |"
    rb"[!#$%&'*+\-.^_`|~0-9A-Za-z]+ [!-~]+ RCTP/[0-9]"
)
#: Bytes of each direction looked at before a connection is taken as not RCTP.
_LOOK = 16
_TRANSPORT_PORT = re.compile(r"(client|server)_port=([0-9]{1,5})")


def _transport_ports(transport: str) -> dict[str, int]:
    """`client_port` and `server_port` of a Transport field (D-RCTP-18)."""
    return {
        f"{side}_port": int(port)
        for side, port in _TRANSPORT_PORT.findall(transport)
        if 0 < int(port) < 65536
    }


# -- TCP -------------------------------------------------------------------------------------------

_MASK = 0xFFFFFFFF
#: Segments held after a hole before the hole is given up as lost from the capture.
_MAX_PENDING = 64


class _Stream:
    """One direction of a TCP connection: its bytes in order, cut into RCTP messages."""

    __slots__ = ("buffer", "needed", "next_seq", "pending")

    def __init__(self) -> None:
        self.next_seq: int | None = None
        self.buffer = bytearray()
        #: Bytes the message at the start of the buffer needs, once its head is known.
        self.needed = 0
        self.pending: dict[int, bytes] = {}

    def add(self, seq: int, syn: bool, payload: bytes) -> bool:
        """Add a segment; True when new bytes joined the buffer."""
        if syn:
            self.next_seq = (seq + 1) & _MASK
            seq = self.next_seq
        if not payload:
            return False
        if self.next_seq is None:
            self.next_seq = seq  # the capture started after the handshake
        ahead = ((seq - self.next_seq + 0x80000000) & _MASK) - 0x80000000
        if ahead < 0:  # a retransmission, maybe with new bytes at its end
            payload = payload[-ahead:]
            ahead = 0
            if not payload:
                return False
        if ahead > 0:
            self.pending[seq] = payload
            if len(self.pending) <= _MAX_PENDING:
                return False
            # A hole the capture will not fill: the message it cut cannot be framed.
            self.buffer.clear()
            self.needed = 0
            start = self.next_seq
            self.next_seq = min(self.pending, key=lambda s: (s - start) & _MASK)
            payload = self.pending.pop(self.next_seq)
        self._append(payload)
        while self.next_seq in self.pending:
            self._append(self.pending.pop(self.next_seq))
        return True

    def _append(self, payload: bytes) -> None:
        self.buffer += payload
        self.next_seq = ((self.next_seq or 0) + len(payload)) & _MASK

    def messages(self) -> Iterator[Packet]:
        """The whole messages at the start of the buffer; Raw for bytes that cannot be framed."""
        while self.buffer and len(self.buffer) >= self.needed:
            data = bytes(self.buffer)
            try:
                length = rctp.message_length(data)
            except rctp.FramingError:
                self.buffer.clear()
                self.needed = 0
                yield conf.raw_layer(data)
                return
            if length is None or length > len(data):
                self.needed = length or 0
                return
            del self.buffer[:length]
            self.needed = 0
            yield rctp.RCTP(data[:length])

    def rest(self) -> Packet | None:
        """What is left when the connection ends: a message cut short, or nothing."""
        if not self.buffer:
            return None
        data = bytes(self.buffer)
        self.buffer.clear()
        self.needed = 0
        return rctp.RCTP(data)


# -- IP and the link layer -------------------------------------------------------------------------


#: Datagrams whose fragments are held at once.
_MAX_DATAGRAMS = 256


class _Fragments:
    """IPv4 datagrams cut into fragments (an RSP packet above the MTU), put back together."""

    def __init__(self) -> None:
        self._parts: dict[tuple[bytes, bytes, int, int], dict[int, bytes]] = {}
        self._ends: dict[tuple[bytes, bytes, int, int], int] = {}

    def add(
        self, key: tuple[bytes, bytes, int, int], offset: int, more: bool, data: bytes
    ) -> bytes | None:
        if key not in self._parts and len(self._parts) >= _MAX_DATAGRAMS:
            # the oldest datagram still missing a fragment will not be completed
            oldest = next(iter(self._parts))
            del self._parts[oldest]
            self._ends.pop(oldest, None)
        parts = self._parts.setdefault(key, {})
        parts[offset] = data
        if not more:
            self._ends[key] = offset + len(data)
        end = self._ends.get(key)
        if end is None:
            return None
        whole = bytearray()
        while len(whole) < end:
            part = parts.get(len(whole))
            if part is None:
                return None
            whole += part
        del self._parts[key]
        del self._ends[key]
        return bytes(whole[:end])


#: Link types whose frames are an IP packet, and where it starts (LINKTYPE_*, pcap-linktype(7)).
_RAW_IP = {101: 0, 12: 0, 14: 0, 228: 0, 229: 0, 0: 4, 108: 4}
_ETHER_IP = {0x0800, 0x86DD}
_VLAN = {0x8100, 0x88A8, 0x9100}


def ip_of_frame(linktype: int, frame: bytes) -> bytes | None:
    """The IP packet a captured frame carries, or None."""
    start = _RAW_IP.get(linktype)
    if start is not None:
        return frame[start:]
    if linktype == 1:  # Ethernet, with any VLAN tags
        offset = 12
        while len(frame) >= offset + 2:
            kind = int.from_bytes(frame[offset : offset + 2], "big")
            if kind in _VLAN:
                offset += 4
                continue
            return frame[offset + 2 :] if kind in _ETHER_IP else None
        return None
    if linktype == 113:  # Linux cooked capture
        kind = int.from_bytes(frame[14:16], "big")
        return frame[16:] if kind in _ETHER_IP else None
    if linktype == 276:  # Linux cooked capture v2
        kind = int.from_bytes(frame[0:2], "big")
        return frame[20:] if kind in _ETHER_IP else None
    layer_class = conf.l2types.num2layer.get(linktype)
    if layer_class is None:
        return None
    from scapy.layers.inet import IP
    from scapy.layers.inet6 import IPv6

    try:
        packet = layer_class(frame)
    except Exception:
        return None
    found = packet.getlayer(IP) or packet.getlayer(IPv6)
    return bytes(found) if found is not None else None


@functools.lru_cache(maxsize=4096)
def _address(raw: bytes) -> str:
    return str(ipaddress.ip_address(raw))


FlowKey = tuple[bytes, int, bytes, int]


class _Pending:
    """A TCP connection on ports not known to be RCTP's, until its first bytes tell."""

    __slots__ = ("looked", "segments")

    def __init__(self) -> None:
        #: The first bytes of each direction: the one that opened it, the other.
        self.looked = [b"", b""]
        #: The segments held meanwhile: (frame, time, key, body).
        self.segments: list[tuple[int, float, FlowKey, bytes]] = []


class Dissector:
    """Feed frames or IP packets in capture order; take the RCTP and RSP messages they carry.

    A UDP flow (one direction) is classified by its first datagram: `decode_as` ports first,
    then the data-stream endpoints a SETUP's answer named (D-RCTP-18), then the default ports,
    then with `heuristics` the datagram itself: a data-stream packet whose layout holds, or an
    RSP header (`rsp.header_fits`). A TCP connection is RCTP on port 7330 or a `decode_as` port,
    to a server endpoint already seen speaking RCTP, or with `heuristics` when its first bytes
    are an RCTP start line. `rcmlconf dissect` classifies flows the same way.
    """

    def __init__(self, decode_as: DecodeAs = (), heuristics: bool = True) -> None:
        self.heuristics = heuristics
        self._tcp_ports = set(DEFAULT_TCP)
        self._udp_ports: dict[int, str] = dict(DEFAULT_UDP)
        self._decode_as_udp: dict[int, str] = {}
        for entry in decode_as:
            proto, port = parse_decode_as(entry) if isinstance(entry, str) else entry
            if proto == RCTP:
                self._tcp_ports.add(port)
            else:
                self._decode_as_udp[port] = proto
        #: UDP flows classified: the protocol, or None for none of ours.
        self._udp: dict[FlowKey, str | None] = {}
        #: The data stream's endpoints SETUP's answers named.
        self._data_endpoints: set[tuple[bytes, int]] = set()
        #: TCP connections (both directions' keys): RCTP, not RCTP, or not known yet.
        self._tcp: dict[FlowKey, bool | _Pending] = {}
        self._rctp_servers: set[tuple[bytes, int]] = set()
        self._streams: dict[FlowKey, _Stream] = {}
        self._last: dict[FlowKey, tuple[int, float]] = {}
        #: The client port of each connection's last SETUP, for its answer (by the answer's key).
        self._setup: dict[FlowKey, int] = {}
        self._fragments = _Fragments()

    def frame(self, number: int, time: float, linktype: int, frame: bytes) -> list[Message]:
        packet = ip_of_frame(linktype, frame)
        return self.ip(number, time, packet) if packet else []

    def ip(self, number: int, time: float, packet: bytes) -> list[Message]:
        version = packet[0] >> 4
        if version == 4 and len(packet) >= 20:
            header = (packet[0] & 0x0F) * 4
            total = int.from_bytes(packet[2:4], "big")
            protocol = packet[9]
            source, destination = packet[12:16], packet[16:20]
            flags = int.from_bytes(packet[6:8], "big")
            body = packet[header:total] if total >= header else packet[header:]
            if flags & 0x3FFF:  # a fragment: more fragments, or an offset
                key = (source, destination, int.from_bytes(packet[4:6], "big"), protocol)
                whole = self._fragments.add(key, (flags & 0x1FFF) * 8, bool(flags & 0x2000), body)
                if whole is None:
                    return []
                body = whole
        elif version == 6 and len(packet) >= 40:
            protocol = packet[6]
            source, destination = packet[8:24], packet[24:40]
            length = int.from_bytes(packet[4:6], "big")
            body = packet[40 : 40 + length]
            while protocol in (0, 43, 60) and len(body) >= 8:  # extension headers
                protocol, body = body[0], body[(body[1] + 1) * 8 :]
            if protocol == 44:
                return []  # IPv6 fragments are not put back together
        else:
            return []
        if protocol == 17 and len(body) >= 8:
            return self._udp_datagram(number, time, source, destination, body)
        if protocol == 6 and len(body) >= 20:
            return self._tcp_segment(number, time, source, destination, body)
        return []

    # -- UDP -------------------------------------------------------------------------------------

    def _udp_datagram(
        self, number: int, time: float, source: bytes, destination: bytes, body: bytes
    ) -> list[Message]:
        sport, dport, length = struct.unpack_from("!HHH", body)
        data = body[8:length] if length >= 8 else body[8:]
        key = (source, sport, destination, dport)
        if key in self._udp:
            proto = self._udp[key]
        else:
            proto = self._udp[key] = self._udp_protocol(key, data)
        if proto is None:
            return []
        layer = rsp.RSP(data) if proto == RSP else rctp.RCTPStream(data)
        ends = (_address(source), sport), (_address(destination), dport)
        return [Message(number, time, proto, *ends, layer)]

    def _udp_protocol(self, key: FlowKey, data: bytes) -> str | None:
        source, sport, destination, dport = key
        chosen = self._decode_as_udp.get(dport) or self._decode_as_udp.get(sport)
        if chosen is not None:
            return chosen
        endpoints = self._data_endpoints
        if (destination, dport) in endpoints or (source, sport) in endpoints:
            return RCTP_DATA
        known = self._udp_ports.get(dport) or self._udp_ports.get(sport)
        if known is not None or not self.heuristics or not data:
            return known
        if data[0] == rctp.RCTP_STREAM_VERSION:
            return RCTP_DATA if rctp.stream_fits(data) else None
        if data[0] == rsp.RSP_VERSION:
            return RSP if rsp.header_fits(data) else None
        return None

    def _learn(self, key: FlowKey, message: Packet) -> None:
        """D-RCTP-18: a SETUP and its answer name the data stream's endpoints."""
        transport = message.header("Transport")
        if transport is None:
            return
        ports = _transport_ports(transport)
        source, sport, destination, dport = key
        if isinstance(message, rctp.RCTPRequest):
            if message.method == b"SETUP" and "client_port" in ports:
                self._setup[(destination, dport, source, sport)] = ports["client_port"]
            return
        if message.status != 200:
            return
        client_port = ports.get("client_port", self._setup.get(key))
        named = ((destination, client_port), (source, ports.get("server_port")))
        fresh = {(address, port) for address, port in named if port} - self._data_endpoints
        if fresh:
            self._data_endpoints |= fresh
            # UDP flows not taken yet are looked at again, as `rcmlconf dissect` does
            for flow in [flow for flow, proto in self._udp.items() if proto is None]:
                del self._udp[flow]

    # -- TCP -------------------------------------------------------------------------------------

    def _tcp_segment(
        self, number: int, time: float, source: bytes, destination: bytes, body: bytes
    ) -> list[Message]:
        sport, dport = struct.unpack_from("!HH", body)
        key = (source, sport, destination, dport)
        known = self._tcp.get(key)
        if known is None:
            known = self._open(key)
        if known is True:
            return self._segment(number, time, key, body)
        if known is False:
            return []
        pending = known
        pending.segments.append((number, time, key, body))
        side = 0 if pending.segments[0][2] == key else 1
        pending.looked[side] += body[(body[12] >> 4) * 4 :]
        decided = self._recognise(pending)
        if decided is None:
            return []
        reverse = (destination, dport, source, sport)
        self._tcp[key] = self._tcp[reverse] = decided
        if not decided:
            return []
        first = pending.segments[0][2]
        for index, looked in enumerate(pending.looked):
            if _START.match(looked) and not looked.startswith(b"RCTP/"):
                # the side that sent a request line is a client: its peer is a server
                server = first[2:] if index == 0 else first[:2]
                self._rctp_servers.add((server[0], server[1]))
        found = []
        for held in pending.segments:
            found.extend(self._segment(*held))
        return found

    def _open(self, key: FlowKey) -> bool | _Pending:
        source, sport, destination, dport = key
        reverse = (destination, dport, source, sport)
        ports, servers = self._tcp_ports, self._rctp_servers
        known: bool | _Pending
        if (
            dport in ports
            or sport in ports
            or (destination, dport) in servers
            or (source, sport) in servers
        ):
            known = True
            if dport in ports:
                servers.add((destination, dport))
            elif sport in ports:
                servers.add((source, sport))
        else:
            known = _Pending() if self.heuristics else False
        self._tcp[key] = self._tcp[reverse] = known
        return known

    @staticmethod
    def _recognise(pending: _Pending) -> bool | None:
        """Whether a connection's first bytes are RCTP's; None to wait for more."""
        looked = pending.looked
        if any(_START.match(data) for data in looked):
            return True
        if any(len(data) >= _LOOK or b"\n" in data for data in looked):
            return False
        return None if len(pending.segments) <= 32 else False

    def _segment(self, number: int, time: float, key: FlowKey, body: bytes) -> list[Message]:
        seq = int.from_bytes(body[4:8], "big")
        offset = (body[12] >> 4) * 4
        flags = body[13]
        stream = self._streams.get(key)
        if stream is None:
            stream = self._streams[key] = _Stream()
        found: list[Packet] = []
        if stream.add(seq, bool(flags & 0x02), body[offset:]):
            found.extend(stream.messages())
        if flags & 0x05:  # FIN or RST: what is left will not be completed
            rest = stream.rest()
            if rest is not None:
                found.append(rest)
            del self._streams[key]
        else:
            self._last[key] = (number, time)
        return [self._control(number, time, key, packet) for packet in found]

    def _control(self, number: int, time: float, key: FlowKey, packet: Packet) -> Message:
        if isinstance(packet, rctp._RCTPMessage):
            self._learn(key, packet)
        source, sport, destination, dport = key
        ends = (_address(source), sport), (_address(destination), dport)
        return Message(number, time, RCTP, *ends, packet)

    def finish(self) -> list[Message]:
        """The end of the capture: what the connections left unfinished."""
        messages = []
        for key, stream in self._streams.items():
            rest = stream.rest()
            if rest is not None:
                number, time = self._last.get(key, (0, 0.0))
                messages.append(self._control(number, time, key, rest))
        self._streams.clear()
        return messages


# -- reading a capture file ------------------------------------------------------------------------


def frames(path: str | os.PathLike[str]) -> Iterator[tuple[int, float, int, bytes]]:
    """(record number from 1, time, link type, bytes) of each record of a pcap or pcapng file."""
    reader = RawPcapReader(os.fspath(path))
    try:
        linktype = getattr(reader, "linktype", None)
        nano = getattr(reader, "nano", False)
        for number, (data, meta) in enumerate(reader, 1):
            info: Any = meta
            if hasattr(info, "tsresol"):  # pcapng: per interface
                time = ((info.tshigh << 32) + info.tslow) / info.tsresol
                yield number, float(time), int(info.linktype), data
            else:
                time = info.sec + info.usec / (1e9 if nano else 1e6)
                yield number, float(time), int(linktype or 0), data
    finally:
        reader.close()


def messages(
    path: str | os.PathLike[str],
    model: RobotModel | str | os.PathLike[str] | None = None,
    decode_as: DecodeAs = (),
    heuristics: bool = True,
) -> Iterator[Message]:
    """The RCTP and RSP messages of a capture, in order, RSP map bodies decoded with `model`
    (raw bytes without one). Raises ValueError for a bad `decode_as`, and scapy's
    Scapy_Exception or OSError for a file that is not a capture."""
    dissector = Dissector(decode_as, heuristics)
    before = rsp.use_model(model)
    try:
        for number, time, linktype, data in frames(path):
            yield from dissector.frame(number, time, linktype, data)
        yield from dissector.finish()
    finally:
        rsp.use_model(before)


def detail(
    path: str | os.PathLike[str],
    model: RobotModel | str | os.PathLike[str] | None = None,
    decode_as: DecodeAs = (),
    heuristics: bool = True,
) -> Iterator[str]:
    """The field tree of each message of `messages(...)`, as scapy's show2() writes it."""
    for message in messages(path, model, decode_as, heuristics):
        yield render(message.packet)


def detail_of(protocol: str, data: bytes) -> str:
    """The field tree of one message's bytes: an RCTP control message (`rctp`), a data-stream
    datagram (`rctp-data`) or an RSP datagram (`rsp`, with the model `rsp.use_model` set)."""
    layers = {RCTP: rctp.RCTP, RCTP_DATA: rctp.RCTPStream, RSP: rsp.RSP}
    return render(layers[protocol](data))


# -- text --------------------------------------------------------------------------------------


def render(packet: Packet, indent: int = 3, lvl: str = "", label_lvl: str = "") -> str:
    """`packet.show(dump=True)`'s text, made without scapy's color-theme calls per field."""
    lines = [f"{label_lvl}###[ {packet.name} ]###\n"]
    fields = list(packet.fields_desc)
    while fields:
        field = fields.pop(0)
        if isinstance(field, ConditionalField) and not field._evalcond(packet):
            continue
        if hasattr(field, "fields"):  # a field with subfields
            lines.append(f"{label_lvl}{lvl}  {field.name} =\n")
            lvl += " " * indent * packet.show_indent
            inner = [f for f in field.fields if hasattr(packet, f.name)]
            fields[0:0] = inner
            continue
        name = field.name
        pad = " " * max(0, 10 - len(name))
        value: Any = packet.getfieldval(name)
        if isinstance(value, Packet) or (
            field.islist and field.holds_packets and isinstance(value, list)
        ):
            lines.append(f"{label_lvl}{lvl}  \\{name}{pad}\\\n")
            for element in value if isinstance(value, list) else [value]:
                lines.append(render(element, indent, "", label_lvl + lvl + "   |"))
            continue
        shown = field.i2repr(packet, value)
        if isinstance(shown, str):
            shown = shown.replace("\n", "\n" + " " * (len(label_lvl) + len(lvl) + len(name) + 4))
        lines.append(f"{label_lvl}{lvl}  {name}{pad}= {shown}\n")
    text = "".join(lines)
    if packet.payload:
        text += render(packet.payload, indent, lvl + " " * indent * packet.show_indent, label_lvl)
    return text


def describe(packet: Packet, protocol: str) -> str:
    """What a summary line says of a message: method and target, status, packet type, ..."""
    if isinstance(packet, rctp._RCTPMessage | rctp.RCTPStream | rsp.RSP):
        return packet.describe()
    name = PROTOCOL_NAMES.get(protocol, protocol)
    return f"{name} cannot be framed ({len(bytes(packet))} bytes)"


def summary(message: Message) -> str:
    """One line: time of day, endpoints, and what the message is."""
    when = datetime.fromtimestamp(message.time).strftime("%H:%M:%S.%f")
    source = _endpoint(message.source)
    destination = _endpoint(message.destination)
    return f"{when} {source} -> {destination} {describe(message.packet, message.protocol)}"


def _endpoint(address: Address) -> str:
    host, port = address
    return f"[{host}]:{port}" if ":" in host else f"{host}:{port}"
