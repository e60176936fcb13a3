"""RCTP and RSP messages of a capture, each dissected by the scapy layers: `rcmlconf dissect -V`
and `rcmlconf sniff`.

Frames are read as `rcmlconf dissect` reads them: the file by `pcap.reader.Capture`, the link
layer, IP (its fragments put back together) and the TCP and UDP headers by `FrameDecoder`, with
`struct` (a scapy packet for those headers costs more than the layers themselves: about 150 µs a
frame against 50), and each direction of a TCP connection is put in order by `tcp.TcpStream`.
scapy dissects the RCTP and RSP bytes only; a direction's bytes are cut into messages by
`rctp.message_length` (Content-Length framing, pipelining, R-RCTP-13). Flows are found by
`rcmlconf dissect`'s own rules (`dissect.classify.Classifier`): default ports, `--decode-as`, the
data-stream endpoints of SETUP's answers (D-RCTP-18), and heuristics.

`render` writes a packet as scapy's `show(dump=True)` does, without its color-theme calls per
field, which cost more than the dissection: `-V` on 10,000 packets takes about 2 s.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Iterator
from datetime import datetime
from typing import TYPE_CHECKING, Any, NamedTuple

from scapy.config import conf
from scapy.fields import ConditionalField
from scapy.packet import Packet

# `rcmlconf sniff` takes RCTP's default ports and name and `parse_decode_as` from here.
from rcmlconf.dissect.classify import DEFAULT_TCP as DEFAULT_TCP
from rcmlconf.dissect.classify import Classifier, FlowKey, Pending, reverse
from rcmlconf.dissect.classify import parse_decode_as as parse_decode_as
from rcmlconf.dissect.records import RCTP as RCTP
from rcmlconf.dissect.records import RCTP_DATA, RSP
from rcmlconf.dissect.tcp import SYN, Piece, TcpStream
from rcmlconf.errors import ValueTextError
from rcmlconf.pcap.addresses import address_text
from rcmlconf.pcap.frames import UDP, FrameDecoder
from rcmlconf.pcap.reader import Capture
from rcmlconf.pcap.records import CaptureError, FrameError
from rcmlconf.rctp.fields import Transport, parse_transport
from rcmlconf.scapy_layers import rctp, rsp

if TYPE_CHECKING:
    from rcmlconf.rsp.model import RobotModel

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


DecodeAs = Iterable[str | tuple[str, int]]

# -- TCP -------------------------------------------------------------------------------------------

#: Segments held behind a hole before it is given up on. `rcmlconf dissect` reads a file and waits
#: for `tcp.MAX_WAITING` bytes (4 MiB); `sniff` prints as frames come, and a segment the capture
#: lost would hold back a control connection's small messages until 4 MiB of them had come.
_MAX_PENDING = 64


class _Stream:
    """One direction of a TCP connection: its bytes in order, cut into RCTP messages."""

    __slots__ = ("buffer", "needed", "syn", "tcp")

    def __init__(self, syn: int | None) -> None:
        #: The sequence number of the SYN that opened it, when the capture holds it.
        self.syn = syn
        self.tcp = TcpStream()
        self.buffer = bytearray()
        #: Bytes the message at the start of the buffer needs, once its head is known.
        self.needed = 0

    def add(self, seq: int, flags: int, payload: bytes) -> list[Packet]:
        """Take a segment; the messages it completed."""
        tcp = self.tcp
        holes = tcp.holes
        found = self._take(tcp.segment(seq, flags, payload, 0, 0.0, -1), tcp.holes != holes)
        if len(tcp.waiting) > _MAX_PENDING:
            found += self._take(tcp.give_up(), True)
        return found

    def end(self) -> list[Packet]:
        """The capture is over: the messages after the holes it never filled, and what is left
        (a message cut short)."""
        found: list[Packet] = []
        while self.tcp.waiting:
            found += self._take(self.tcp.give_up(), True)
        rest = self.rest()
        return [*found, rest] if rest is not None else found

    def _take(self, pieces: list[Piece], hole: bool) -> list[Packet]:
        """The messages bytes in order complete. Before a hole the capture lost, what the buffer
        holds is a message cut short: nothing is framed across the hole."""
        found: list[Packet] = []
        if hole:
            rest = self.rest()
            if rest is not None:
                found.append(rest)
        for piece in pieces:
            self.buffer += piece[1]
        if pieces:
            found.extend(self.messages())
        return found

    def _clear(self) -> None:
        self.buffer.clear()
        self.needed = 0

    def messages(self) -> Iterator[Packet]:
        """The whole messages at the start of the buffer; Raw for bytes that cannot be framed."""
        while self.buffer and len(self.buffer) >= self.needed:
            data = bytes(self.buffer)
            try:
                length = rctp.message_length(data)
            except rctp.FramingError:
                self._clear()
                yield conf.raw_layer(data)
                return
            if length is None or length > len(data):
                self.needed = length or 0
                return
            del self.buffer[:length]
            self.needed = 0
            yield rctp.RCTP(data[:length])

    def rest(self) -> Packet | None:
        """What the buffer holds when the connection ends or the capture lost bytes: a message
        cut short, or nothing."""
        if not self.buffer:
            return None
        data = bytes(self.buffer)
        self._clear()
        return rctp.RCTP(data)


#: A segment of a connection held by `Pending`: (frame, time, key, sequence number, flags, payload).
_Held = tuple[int, float, FlowKey, int, int, bytes]


class Dissector:
    """Feed frames in capture order; take the RCTP and RSP messages they carry, each flow's
    protocol found by `Classifier` (`decode_as` ports, SETUP's answers, the default ports, and
    with `heuristics` a flow's first packet), as `rcmlconf dissect` finds it."""

    def __init__(self, decode_as: DecodeAs = (), heuristics: bool = True) -> None:
        chosen = [parse_decode_as(e) if isinstance(e, str) else e for e in decode_as]
        self._flows = Classifier(chosen, heuristics)
        #: UDP flows classified: the protocol, or None for none of ours.
        self._udp: dict[FlowKey, str | None] = {}
        #: TCP connections (both directions' keys): RCTP, not RCTP, or not known yet.
        self._tcp: dict[FlowKey, bool | Pending[_Held]] = {}
        self._streams: dict[FlowKey, _Stream] = {}
        self._last: dict[FlowKey, tuple[int, float]] = {}
        #: The Transport of each connection's last SETUP, for its answer (by the answer's key).
        self._setup: dict[FlowKey, Transport] = {}
        self._frames = FrameDecoder()

    def frame(self, number: int, time: float, linktype: int, frame: bytes) -> list[Message]:
        """The messages a frame completes; `linktype` is its link type (LINKTYPE_*)."""
        try:
            segment = self._frames.decode(frame, 0, len(frame), linktype)
        except FrameError:
            return []  # headers that cannot be read: no message in them (`rcmlconf dissect` says)
        if segment is None:
            return []
        protocol, source, sport, destination, dport, payload, _, seq, flags, _ = segment
        key = (source, sport, destination, dport)
        if protocol == UDP:
            return self._udp_datagram(number, time, key, payload)
        return self._tcp_segment(number, time, key, seq, flags, payload)

    # -- UDP -------------------------------------------------------------------------------------

    def _udp_datagram(self, number: int, time: float, key: FlowKey, data: bytes) -> list[Message]:
        if key in self._udp:
            proto = self._udp[key]
        else:
            proto = self._udp[key] = self._flows.udp(key, data)
        if proto is None:
            return []
        layer = rsp.RSP(data) if proto == RSP else rctp.RCTPStream(data)
        return [Message(number, time, proto, *_ends(key), layer)]

    def _learn(self, key: FlowKey, message: Packet) -> None:
        """D-RCTP-18, D-RCTP-28: a SETUP's 200 names the data stream's endpoints: the client's
        port (the answer's client_port, else the SETUP's) and the server's; learnt as
        `rcmlconf dissect` learns them, from a Transport the core reads and that gives a tag."""
        text = message.header("Transport")
        is_request = isinstance(message, rctp.RCTPRequest)
        if text is None or (message.method != b"SETUP" if is_request else message.status != 200):
            return
        try:
            transport = parse_transport(text)
        except ValueTextError:
            return  # `rcmlconf dissect` reports it (R-RCTP-38)
        if is_request:
            self._setup[reverse(key)] = transport
            return
        if transport.tag is None:
            return
        asked = self._setup.get(key)
        client_port = transport.client_port or (asked.client_port if asked else None)
        source, _, destination, _ = key
        if self._flows.learn((destination, client_port), (source, transport.server_port)):
            # UDP flows not taken yet are looked at again, as `rcmlconf dissect` does
            for flow in [flow for flow, proto in self._udp.items() if proto is None]:
                del self._udp[flow]

    # -- TCP -------------------------------------------------------------------------------------

    def _tcp_segment(
        self, number: int, time: float, key: FlowKey, seq: int, flags: int, payload: bytes
    ) -> list[Message]:
        known = self._tcp.get(key)
        if known is None:
            rctp_flow = self._flows.tcp(key)
            known = Pending(key) if rctp_flow is None else rctp_flow
            self._tcp[key] = self._tcp[reverse(key)] = known
        if known is True:
            return self._segment(number, time, key, seq, flags, payload)
        if known is False:
            return []
        pending = known
        side = 0 if pending.first == key else 1
        decided = self._flows.look(pending, side, (number, time, key, seq, flags, payload), payload)
        if decided is None:
            return []
        self._tcp[key] = self._tcp[reverse(key)] = decided
        if not decided:
            return []
        found = []
        for held in pending.segments:
            found.extend(self._segment(*held))
        return found

    def _segment(
        self, number: int, time: float, key: FlowKey, seq: int, flags: int, payload: bytes
    ) -> list[Message]:
        found: list[Packet] = []
        stream = self._streams.get(key)
        if stream is None or (flags & SYN and seq != stream.syn):
            # The first segment seen, or a SYN that is not this one's again: a new connection
            # between the same ports. What the last one left is all it will have.
            if stream is not None:
                found = stream.end()
            stream = self._streams[key] = _Stream(seq if flags & SYN else None)
        found += stream.add(seq, flags, payload)
        if stream.tcp.finished:  # FIN or RST: what is left will not be completed
            rest = stream.rest()
            if rest is not None:
                found.append(rest)
        self._last[key] = (number, time)
        return [self._control(number, time, key, packet) for packet in found]

    def _control(self, number: int, time: float, key: FlowKey, packet: Packet) -> Message:
        if isinstance(packet, rctp._RCTPMessage):
            self._learn(key, packet)
        return Message(number, time, RCTP, *_ends(key), packet)

    def finish(self) -> list[Message]:
        """The end of the capture: what the connections left unfinished."""
        messages: list[Message] = []
        for key, stream in self._streams.items():
            number, time = self._last[key]
            messages.extend(self._control(number, time, key, packet) for packet in stream.end())
        self._streams.clear()
        return messages


def _ends(key: FlowKey) -> tuple[Address, Address]:
    source, sport, destination, dport = key
    return (address_text(source), sport), (address_text(destination), dport)


# -- reading a capture file ------------------------------------------------------------------------


def messages(
    capture: Capture | str | os.PathLike[str],
    model: RobotModel | str | os.PathLike[str] | None = None,
    decode_as: DecodeAs = (),
    heuristics: bool = True,
) -> Iterator[Message]:
    """The RCTP and RSP messages of a capture (open, or a file's path), in order, RSP map bodies
    decoded with `model` (raw bytes without one). Raises ValueError for a bad `decode_as`,
    OSError for a file that cannot be read, and `CaptureError` for one that is not a capture, or,
    after the messages before it, where its structure breaks (`rcmlconf dissect` reads that far
    too)."""
    if not isinstance(capture, Capture):
        with Capture.open(capture) as opened:
            yield from messages(opened, model, decode_as, heuristics)
        return
    dissector = Dissector(decode_as, heuristics)
    before = rsp.use_model(model)
    try:
        broken: CaptureError | None = None
        try:
            for number, (time, linktype, frame) in enumerate(capture.frames(), 1):
                yield from dissector.frame(number, time, linktype, frame)
        except CaptureError as error:
            broken = error
        yield from dissector.finish()
        if broken is not None:
            raise broken
    finally:
        rsp.use_model(before)


def detail(
    capture: Capture | str | os.PathLike[str],
    model: RobotModel | str | os.PathLike[str] | None = None,
    decode_as: DecodeAs = (),
    heuristics: bool = True,
) -> Iterator[str]:
    """The field tree of each message of `messages(...)`, as scapy's show2() writes it."""
    for message in messages(capture, model, decode_as, heuristics):
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
