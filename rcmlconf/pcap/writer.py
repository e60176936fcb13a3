"""A classic pcap file (LINKTYPE_RAW: each record an IPv4 or IPv6 packet) made from application
payloads.

The harness sees its TCP traffic as bytes written and read, not as segments. To give dissectors
(ours, tshark) a capture they read as they would a real one, each TCP flow gets a three-way
handshake before its first payload, sequence and acknowledgement numbers that follow the bytes,
and segments of at most `MSS` bytes; every checksum is computed. UDP datagrams are written as
they are.

A capture that leaves payloads out (`Gap`: a bounded transcript kept only the first and the last
of a flood) is pcapng instead, with the same packets, so that it can say so: a comment on the
block of the flow's next packet, or, for flows none of whose payloads are kept, on the section.
A TCP flow's sequence numbers go on past the bytes left out: a dissector sees a hole in the
stream, not bytes spliced together.
"""

from __future__ import annotations

import functools
import ipaddress
import struct
from collections.abc import Iterable
from dataclasses import dataclass
from typing import BinaryIO

Address = tuple[str, int]

#: pcap's magic (microsecond stamps), version 2.4, snap length, LINKTYPE_RAW.
_GLOBAL = struct.pack("<IHHiIII", 0xA1B2C3D4, 2, 4, 0, 0, 65535, 101)
MSS = 1460
_SYN, _ACK, _PSH = 0x02, 0x10, 0x08
#: The first sequence number of each side of a flow: fixed, so a capture is reproducible.
_ISN = 1000
#: pcapng: the blocks' types, the byte-order magic, and the options' codes.
_SHB, _IDB, _EPB = 0x0A0D0D0A, 1, 6
_BYTE_ORDER = 0x1A2B3C4D
_OPT_END, _OPT_COMMENT = 0, 1
_RAW = 101


@dataclass(frozen=True, slots=True)
class Payload:
    at: float
    transport: str  # "tcp" or "udp"
    source: Address
    destination: Address
    data: bytes


@dataclass(frozen=True, slots=True)
class Gap:
    """Payloads of the flow from `source` to `destination` (of `transport`) that the capture
    leaves out, `size` bytes in all, before its next payload; `comment` says so. Without
    endpoints: of flows none of whose payloads the capture holds."""

    source: Address | None
    destination: Address | None
    transport: str
    comment: str
    size: int = 0


class PcapWriter:
    """Payloads as packets, in order; `comments`: pcapng, whose blocks can say what was left
    out (`leave_out`), `notes` on its section; else classic pcap."""

    def __init__(
        self, file: BinaryIO, *, comments: bool = False, notes: Iterable[str] = ()
    ) -> None:
        self._file = file
        self._pcapng = comments
        if comments:
            self._file.write(_block(_SHB, struct.pack("<IHHq", _BYTE_ORDER, 1, 0, -1), notes))
            self._file.write(_block(_IDB, struct.pack("<HHI", _RAW, 0, 65535)))
        else:
            self._file.write(_GLOBAL)
        #: (source, destination) -> next sequence number of that direction.
        self._next: dict[tuple[Address, Address], int] = {}
        #: (source, destination) -> what the block of that direction's next packet says.
        self._said: dict[tuple[Address, Address], str] = {}

    def leave_out(self, gap: Gap) -> None:
        """Payloads left out here: said on the block of the flow's next packet (pcapng); a TCP
        flow's sequence numbers move on past their bytes."""
        if gap.source is None or gap.destination is None:
            return
        forward = (gap.source, gap.destination)
        self._said[forward] = gap.comment
        if gap.transport == "tcp" and forward in self._next:
            self._next[forward] = (self._next[forward] + gap.size) & 0xFFFFFFFF

    def write(self, payload: Payload) -> None:
        if payload.transport == "udp":
            packet = _udp(payload.source, payload.destination, payload.data)
            self._record(payload.at, packet, (payload.source, payload.destination))
            return
        forward = (payload.source, payload.destination)
        if forward not in self._next:
            self._handshake(payload.at, payload.source, payload.destination)
        data = payload.data
        for start in range(0, max(len(data), 1), MSS):
            chunk = data[start : start + MSS]
            self._segment(payload.at, payload.source, payload.destination, _ACK | _PSH, chunk)

    def _handshake(self, at: float, client: Address, server: Address) -> None:
        """SYN, SYN-ACK, ACK, as if the side that spoke first had opened the connection."""
        self._next[(client, server)] = _ISN
        self._next[(server, client)] = _ISN
        self._segment(at, client, server, _SYN, b"", syn=True)
        self._segment(at, server, client, _SYN | _ACK, b"", syn=True)
        self._segment(at, client, server, _ACK, b"")

    def _segment(
        self,
        at: float,
        source: Address,
        destination: Address,
        flags: int,
        data: bytes,
        syn: bool = False,
    ) -> None:
        seq = self._next[(source, destination)]
        ack = self._next[(destination, source)] if flags & _ACK else 0
        self._next[(source, destination)] = (seq + len(data) + (1 if syn else 0)) & 0xFFFFFFFF
        self._record(at, _tcp(source, destination, seq, ack, flags, data), (source, destination))

    def _record(self, at: float, packet: bytes, way: tuple[Address, Address] | None = None) -> None:
        if self._pcapng:
            said = self._said.pop(way, None) if way is not None else None
            stamp = round(at * 1_000_000)
            head = struct.pack(
                "<IIIII", 0, stamp >> 32, stamp & 0xFFFFFFFF, len(packet), len(packet)
            )
            self._file.write(_block(_EPB, head + _padded(packet), [said] if said else []))
            return
        seconds = int(at)
        micros = round((at - seconds) * 1_000_000)
        if micros >= 1_000_000:
            seconds, micros = seconds + 1, micros - 1_000_000
        self._file.write(struct.pack("<IIII", seconds, micros, len(packet), len(packet)))
        self._file.write(packet)


def write_pcap(file: BinaryIO, payloads: Iterable[Payload | Gap]) -> None:
    """The payloads as a capture: classic pcap, or pcapng that says where any `Gap` is."""
    payloads = list(payloads)
    gaps = [g for g in payloads if isinstance(g, Gap)]
    notes = [g.comment for g in gaps if g.source is None or g.destination is None]
    writer = PcapWriter(file, comments=bool(gaps), notes=notes)
    for item in payloads:
        if isinstance(item, Gap):
            writer.leave_out(item)
        else:
            writer.write(item)


def _padded(data: bytes) -> bytes:
    return data + b"\0" * (-len(data) % 4)


def _block(kind: int, body: bytes, comments: Iterable[str] = ()) -> bytes:
    """A pcapng block (little-endian), `comments` as its opt_comment options."""
    options = b"".join(
        struct.pack("<HH", _OPT_COMMENT, len(text)) + _padded(text)
        for text in (comment.encode() for comment in comments)
    )
    if options:
        options += struct.pack("<HH", _OPT_END, 0)
    total = 12 + len(body) + len(options)
    return struct.pack("<II", kind, total) + body + options + struct.pack("<I", total)


def _checksum(data: bytes) -> int:
    if len(data) % 2:
        data += b"\0"
    total: int = sum(struct.unpack(f"!{len(data) // 2}H", data))
    while total >> 16:
        total = (total & 0xFFFF) + (total >> 16)
    return ~total & 0xFFFF


def _ip(source: str, destination: str, protocol: int, body: bytes) -> bytes:
    """An IPv4 or IPv6 packet (its addresses say which) around `body`."""
    src, dst = _packed(source, destination)
    if len(src) == 16:
        header6 = struct.pack("!IHBB", 6 << 28, len(body), protocol, 64)
        return header6 + src + dst + body
    header = struct.pack(
        "!BBHHHBBH4s4s", 0x45, 0, 20 + len(body), 0, 0x4000, 64, protocol, 0, src, dst
    )
    return header[:10] + struct.pack("!H", _checksum(header)) + header[12:] + body


def _pseudo(source: str, destination: str, protocol: int, length: int) -> bytes:
    """The pseudo-header of a TCP or UDP checksum: RFC 768/793's for IPv4, RFC 8200's for IPv6."""
    src, dst = _packed(source, destination)
    if len(src) == 16:
        return src + dst + struct.pack("!IxxxB", length, protocol)
    return src + dst + struct.pack("!BBH", 0, protocol, length)


@functools.lru_cache(maxsize=256)
def _packed(source: str, destination: str) -> tuple[bytes, bytes]:
    """The two addresses' bytes: 4 each, or 16 each when either is IPv6 (an IPv4 one mapped).
    Kept: a capture names few addresses, and parsing them cost a third of writing one."""
    src, dst = ipaddress.ip_address(source), ipaddress.ip_address(destination)
    if src.version == 6 or dst.version == 6:
        return _v6(src).packed, _v6(dst).packed
    return src.packed, dst.packed


def _v6(address: ipaddress.IPv4Address | ipaddress.IPv6Address) -> ipaddress.IPv6Address:
    """`address` as IPv6 (an IPv4 one mapped), for a packet whose other end is IPv6."""
    if isinstance(address, ipaddress.IPv6Address):
        return address
    return ipaddress.IPv6Address(f"::ffff:{address}")


def _udp(source: Address, destination: Address, data: bytes) -> bytes:
    length = 8 + len(data)
    header = struct.pack("!HHHH", source[1], destination[1], length, 0)
    checksum = _checksum(_pseudo(source[0], destination[0], 17, length) + header + data) or 0xFFFF
    return _ip(source[0], destination[0], 17, header[:6] + struct.pack("!H", checksum) + data)


def _tcp(
    source: Address, destination: Address, seq: int, ack: int, flags: int, data: bytes
) -> bytes:
    header = struct.pack(
        "!HHIIBBHHH", source[1], destination[1], seq, ack, 5 << 4, flags, 65535, 0, 0
    )
    checksum = _checksum(_pseudo(source[0], destination[0], 6, 20 + len(data)) + header + data)
    return _ip(
        source[0], destination[0], 6, header[:16] + struct.pack("!H", checksum) + header[18:] + data
    )
