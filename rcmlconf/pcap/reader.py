"""Read pcap and pcapng captures, and the IPv4/IPv6, TCP and UDP headers of their frames.

Built for speed with `struct` over the file's bytes (a memory map, or bytes): no object per record
but a tuple, and no copy of a frame until its transport payload is sliced out.

- `Capture.records()` yields `(time, linktype, start, end, length)` for each packet record:
  the frame is `capture.data[start:end]`, `length` its length on the wire (more than
  `end - start` when the snap length cut it). `Capture.frames()` yields `(time, linktype, frame)`.
- Formats: classic pcap in both byte orders, with microsecond and nanosecond stamps; pcapng
  (Section Header, Interface Description, Enhanced, Simple and the obsolete Packet blocks), each
  interface with its own link type, `if_tsresol` and `if_tsoffset`, sections in either byte order.
- `FrameDecoder.decode(...)` reads a frame's link layer (Ethernet with VLAN tags, raw IP, Linux
  cooked SLL and SLL2, BSD loopback/NULL), IPv4 (fragments reassembled) or IPv6 (extension headers
  skipped, fragments reassembled), and TCP or UDP, and returns the transport's fields and payload.

The only exception either lets escape is `CaptureError`, a `ProtocolError` whose offset counts
bytes from the start of the file: the file's structure is broken there (`records`), or a frame's
headers are (`decode`, a `FrameError`: the records after it are still readable).
"""

from __future__ import annotations

import mmap
import os
import socket
import stat
import struct
from collections import OrderedDict
from collections.abc import Iterator
from pathlib import Path
from types import TracebackType
from typing import BinaryIO, Final

from rcmlconf.errors import ProtocolError
from rcmlconf.wording import plural

LINKTYPE_NULL: Final = 0
LINKTYPE_ETHERNET: Final = 1
LINKTYPE_RAW: Final = 101
LINKTYPE_LOOP: Final = 108
LINKTYPE_LINUX_SLL: Final = 113
LINKTYPE_IPV4: Final = 228
LINKTYPE_IPV6: Final = 229
LINKTYPE_LINUX_SLL2: Final = 276
LINK_TYPES: Final = {
    LINKTYPE_NULL: "BSD loopback",
    LINKTYPE_ETHERNET: "Ethernet",
    LINKTYPE_RAW: "raw IP",
    LINKTYPE_LOOP: "OpenBSD loopback",
    LINKTYPE_LINUX_SLL: "Linux cooked (SLL)",
    LINKTYPE_IPV4: "raw IPv4",
    LINKTYPE_IPV6: "raw IPv6",
    LINKTYPE_LINUX_SLL2: "Linux cooked (SLL2)",
}

TCP: Final = 6
UDP: Final = 17

#: A packet record: time (Unix seconds), link type, the frame's start and end in `Capture.data`,
#: and its length on the wire.
Record = tuple[float, int, int, int, int]

_PCAP_MAGIC = {
    # magic as read little-endian -> (byte order, seconds per stamp unit)
    0xA1B2C3D4: ("<", 1e-6),
    0xD4C3B2A1: (">", 1e-6),
    0xA1B23C4D: ("<", 1e-9),
    0x4D3CB2A1: (">", 1e-9),
}
_PCAP_HEADER = 24
#: What a capture read from a pipe or a device may hold (in memory); a file is mapped instead.
MAX_STREAM: Final = 1 << 30
_CHUNK = 1 << 20
_SHB = 0x0A0D0D0A
_IDB = 1
_OPB = 2
_SPB = 3
_EPB = 6
_BYTE_ORDER_MAGIC = 0x1A2B3C4D
#: pcapng's option codes of an Interface Description Block.
_OPT_END, _OPT_TSRESOL, _OPT_TSOFFSET = 0, 9, 14


class CaptureError(ProtocolError):
    """A capture file, or a frame in it, that cannot be read; `offset` counts from the file's
    start."""


class FrameError(CaptureError):
    """One frame's link, IP or transport header is broken; the records after it can be read."""


class Capture:
    """The records of one capture file. `data` is the file's bytes (a memory map when opened
    with `open`); `format` is `"pcap"` or `"pcapng"`."""

    def __init__(self, data: bytes | mmap.mmap, name: str = "<capture>") -> None:
        self.data = data
        self.name = name
        self._mmap = data if isinstance(data, mmap.mmap) else None
        self.format = _detect(data)

    @classmethod
    def open(cls, path: str | os.PathLike[str]) -> Capture:
        """Map the file; OSError when it cannot be read, CaptureError when it is no capture."""
        with Path(path).open("rb") as file:
            status = os.fstat(file.fileno())
            if not stat.S_ISREG(status.st_mode) or status.st_size == 0:
                # A pipe or a device (/dev/stdin, <(tcpdump -w -)), like a file of /proc, says it
                # holds 0 bytes, whatever it gives: nothing to map, but a stream to read.
                return cls.read(file, str(path))
            mapped = mmap.mmap(file.fileno(), 0, access=mmap.ACCESS_READ)
        try:
            return cls(mapped, str(path))
        except CaptureError:
            mapped.close()
            raise

    @classmethod
    def read(cls, stream: BinaryIO, name: str, limit: int = MAX_STREAM) -> Capture:
        """A capture from a stream, read as it comes: its header is checked before the rest is
        read, so that /dev/zero or /dev/urandom is refused at once; at most `limit` bytes."""
        head = stream.read(_PCAP_HEADER)
        _detect(head)  # a header cut short is only read so when the stream ends there
        chunks, size = [head], len(head)
        while size <= limit and (chunk := stream.read(_CHUNK)):
            chunks.append(chunk)
            size += len(chunk)
        if size > limit:
            raise CaptureError(
                f"more than {limit:,} bytes from a pipe or a device: save the capture to a file,"
                " which is read whatever its size",
                limit,
            )
        return cls(b"".join(chunks), name)

    def close(self) -> None:
        if self._mmap is not None:
            self._mmap.close()
            self._mmap = None

    def __enter__(self) -> Capture:
        return self

    def __exit__(
        self,
        kind: type[BaseException] | None,
        value: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        self.close()

    @property
    def decimals(self) -> int:
        """Decimals of a second the stamps have: 6 (microseconds) or 9 (nanoseconds); for
        pcapng, the finest of the interfaces described before the first packet."""
        if self.format == "pcap":
            return 6 if _PCAP_MAGIC[struct.unpack_from("<I", self.data, 0)[0]][1] == 1e-6 else 9
        divisors = [1_000_000]
        try:
            for block in _pcapng_interfaces(self.data):
                divisors.append(block)
        except CaptureError:
            pass
        finest = max(divisors)
        return 6 if finest <= 1_000_000 else 9

    def first_time(self) -> float | None:
        """The stamp of the first packet record, None when there is none (or it is broken)."""
        try:
            for record in self.records():
                return record[0]
        except CaptureError:
            return None
        return None

    def records(self) -> Iterator[Record]:
        """Every packet record in file order; CaptureError where the structure breaks."""
        if self.format == "pcap":
            return _pcap_records(self.data)
        return _pcapng_records(self.data)

    def frames(self) -> Iterator[tuple[float, int, bytes]]:
        """`(time, linktype, frame bytes)` of every packet record."""
        data = self.data
        for time, linktype, start, end, _ in self.records():
            yield time, linktype, bytes(data[start:end])


def _detect(data: bytes | mmap.mmap) -> str:
    if len(data) < 4:
        raise CaptureError(f"{plural(len(data), 'byte')}: too short for a pcap or pcapng file", 0)
    (magic,) = struct.unpack_from("<I", data, 0)
    if magic in _PCAP_MAGIC:
        if len(data) < _PCAP_HEADER:
            raise CaptureError(
                f"pcap file header of {len(data)} bytes, not {_PCAP_HEADER}", len(data)
            )
        return "pcap"
    if magic == _SHB:
        return "pcapng"
    raise CaptureError(
        f"not a pcap or pcapng file (it starts with {bytes(data[:4]).hex()},"
        " no capture format's magic number)",
        0,
    )


# -- pcap ------------------------------------------------------------------------------------


def _pcap_records(data: bytes | mmap.mmap) -> Iterator[Record]:
    (magic,) = struct.unpack_from("<I", data, 0)
    order, unit = _PCAP_MAGIC[magic]
    major, _minor, _zone, _figures, _snap, network = struct.unpack_from(order + "HHiIII", data, 4)
    if major != 2:
        raise CaptureError(f"pcap version {major}, not 2", 4)
    linktype = network & 0xFFFF
    unpack = struct.Struct(order + "IIII").unpack_from
    size = len(data)
    offset = _PCAP_HEADER
    while offset < size:
        if size - offset < 16:
            raise CaptureError(
                f"the file ends inside a record header ({size - offset} of 16 bytes)", offset
            )
        seconds, fraction, captured, length = unpack(data, offset)
        start = offset + 16
        end = start + captured
        if end > size:
            raise CaptureError(
                f"record of {plural(captured, 'byte')} runs past the end of the file"
                f" ({plural(size - start, 'byte')} left)",
                offset + 8,
            )
        yield seconds + fraction * unit, linktype, start, end, length
        offset = end


# -- pcapng ----------------------------------------------------------------------------------


class _Interface:
    __slots__ = ("divisor", "linktype", "offset", "snaplen")

    def __init__(self, linktype: int, snaplen: int, divisor: int, offset: int) -> None:
        self.linktype = linktype
        self.snaplen = snaplen
        #: Stamp units per second (if_tsresol) and seconds to add (if_tsoffset).
        self.divisor = divisor
        self.offset = offset


def _pcapng_records(data: bytes | mmap.mmap) -> Iterator[Record]:
    size = len(data)
    offset = 0
    order = ""
    interfaces: list[_Interface] = []
    last_time = 0.0
    u32: struct.Struct | None = None
    while offset < size:
        if size - offset < 12:
            raise CaptureError(
                f"the file ends inside a block header ({size - offset} of 12 bytes)", offset
            )
        if struct.unpack_from("<I", data, offset)[0] == _SHB:
            (magic,) = struct.unpack_from("<I", data, offset + 8)
            if magic == _BYTE_ORDER_MAGIC:
                order = "<"
            elif magic == int.from_bytes(_BYTE_ORDER_MAGIC.to_bytes(4, "little"), "big"):
                order = ">"
            else:
                raise CaptureError(
                    "section header: byte-order magic is neither 1a2b3c4d nor 4d3c2b1a",
                    offset + 8,
                )
            u32 = struct.Struct(order + "I")
            interfaces = []
        elif u32 is None:
            raise CaptureError("a pcapng file starts with a Section Header Block", offset)
        assert u32 is not None
        kind, total = struct.unpack_from(order + "II", data, offset)
        if total < 12 or total % 4:
            raise CaptureError(
                f"block length {total} is not a multiple of 4 of at least 12", offset + 4
            )
        if total > size - offset:
            raise CaptureError(
                f"block of {total} bytes runs past the end of the file"
                f" ({size - offset} bytes left)",
                offset + 4,
            )
        end = offset + total
        if u32.unpack_from(data, end - 4)[0] != total:
            raise CaptureError(
                f"block's trailing length is not its leading length {total}", end - 4
            )
        body = offset + 8
        body_end = end - 4
        if kind == _EPB:
            if total < 32:
                raise CaptureError(f"Enhanced Packet Block of {total} bytes, fewer than 32", offset)
            number, high, low, captured, length = struct.unpack_from(order + "IIIII", data, body)
            interface = _interface(interfaces, number, body)
            start = body + 20
            if captured > body_end - start:
                raise CaptureError(
                    f"packet of {plural(captured, 'byte')} does not fit its block", body + 12
                )
            last_time = ((high << 32) | low) / interface.divisor + interface.offset
            yield last_time, interface.linktype, start, start + captured, length
        elif kind == _SPB:
            if total < 16:
                raise CaptureError(f"Simple Packet Block of {total} bytes, fewer than 16", offset)
            (length,) = u32.unpack_from(data, body)
            interface = _interface(interfaces, 0, body)
            start = body + 4
            captured = min(length, body_end - start)
            if interface.snaplen:
                captured = min(captured, interface.snaplen)
            # A Simple Packet Block has no stamp: the packet gets the time of the one before.
            yield last_time, interface.linktype, start, start + captured, length
        elif kind == _OPB:
            if total < 32:
                raise CaptureError(f"Packet Block of {total} bytes, fewer than 32", offset)
            number, _drops, high, low, captured, length = struct.unpack_from(
                order + "HHIIII", data, body
            )
            interface = _interface(interfaces, number, body)
            start = body + 20
            if captured > body_end - start:
                raise CaptureError(
                    f"packet of {plural(captured, 'byte')} does not fit its block", body + 12
                )
            last_time = ((high << 32) | low) / interface.divisor + interface.offset
            yield last_time, interface.linktype, start, start + captured, length
        elif kind == _IDB:
            if total < 20:
                raise CaptureError(
                    f"Interface Description Block of {total} bytes, fewer than 20", offset
                )
            linktype, _reserved, snaplen = struct.unpack_from(order + "HHI", data, body)
            divisor, seconds = _interface_options(data, order, body + 8, body_end)
            interfaces.append(_Interface(linktype, snaplen, divisor, seconds))
        elif kind == _SHB:
            if total < 28:
                raise CaptureError(f"Section Header Block of {total} bytes, fewer than 28", offset)
            (major,) = struct.unpack_from(order + "H", data, body + 4)
            if major != 1:
                raise CaptureError(f"pcapng version {major}, not 1", body + 4)
        # Any other block (name resolution, statistics, secrets, custom) is skipped.
        offset = end


def _pcapng_interfaces(data: bytes | mmap.mmap) -> Iterator[int]:
    """The stamp units per second of each interface described before the first packet."""
    size = len(data)
    offset = 0
    order = "<"
    while size - offset >= 12:
        if struct.unpack_from("<I", data, offset)[0] == _SHB:
            magic = struct.unpack_from("<I", data, offset + 8)[0]
            order = "<" if magic == _BYTE_ORDER_MAGIC else ">"
        kind, total = struct.unpack_from(order + "II", data, offset)
        if total < 12 or total % 4 or total > size - offset:
            return
        if kind in (_EPB, _SPB, _OPB):
            return
        if kind == _IDB and total >= 20:
            yield _interface_options(data, order, offset + 16, offset + total - 4)[0]
        offset += total


def _interface(interfaces: list[_Interface], number: int, where: int) -> _Interface:
    if number >= len(interfaces):
        raise CaptureError(
            f"packet of interface {number}, but the section describes {len(interfaces)}", where
        )
    return interfaces[number]


def _interface_options(
    data: bytes | mmap.mmap, order: str, offset: int, end: int
) -> tuple[int, int]:
    """if_tsresol as stamp units per second, and if_tsoffset in seconds."""
    divisor, seconds = 1_000_000, 0
    while end - offset >= 4:
        code, length = struct.unpack_from(order + "HH", data, offset)
        value = offset + 4
        if code == _OPT_END:
            break
        if length > end - value:
            raise CaptureError(
                f"option {code} of {plural(length, 'byte')} runs past its block", offset
            )
        if code == _OPT_TSRESOL and length >= 1:
            resolution = data[value]
            exponent = resolution & 0x7F
            if resolution & 0x80:
                divisor = 1 << exponent
            else:
                if exponent > 18:
                    raise CaptureError(f"if_tsresol of 10^-{exponent} s", value)
                divisor = 10**exponent
        elif code == _OPT_TSOFFSET and length >= 8:
            (seconds,) = struct.unpack_from(order + "q", data, value)
        offset = value + (length + 3) // 4 * 4
    return divisor, seconds


# -- frames ------------------------------------------------------------------------------------

#: A transport segment or datagram: protocol (TCP or UDP), source address (4 or 16 bytes), source
#: port, destination address, destination port, payload, the payload's offset in the file (-1 for
#: a datagram put together from fragments), TCP sequence number and flags (0 for UDP), and
#: whether the frame was cut short by the snap length (the payload is then partial).
Segment = tuple[int, bytes, int, bytes, int, bytes, int, int, int, bool]

_ETHERTYPE_IPV4 = 0x0800
_ETHERTYPE_IPV6 = 0x86DD
_ETHERTYPE_VLAN = frozenset({0x8100, 0x88A8, 0x9100})
#: DLT_RAW as some systems number it (12, and 14 on OpenBSD), in files written before LINKTYPE_RAW
#: (101) took its place: raw IP, as Wireshark reads them.
_DLT_RAW = frozenset({12, 14})
#: BSD loopback's address families of IPv6 (they differ by system).
_AF_INET6 = frozenset({24, 28, 30})
_IPV6_EXTENSIONS = frozenset({0, 43, 60})
_IPV6_FRAGMENT = 44
_IPV6_AH = 51
_IPV4_UDP = struct.Struct("!BBHHHBBH4s4sHHH")
_IPV4 = struct.Struct("!BBHHHBB2x4s4s")
_IPV6 = struct.Struct("!4xHBB16s16s")
_TCP = struct.Struct("!HHIIBB")
_UDP = struct.Struct("!HHH")
_U16 = struct.Struct("!H")
#: Datagrams being put together from fragments, at most this many at once.
MAX_REASSEMBLIES = 256


class _Fragments:
    __slots__ = ("parts", "total")

    def __init__(self) -> None:
        self.parts: dict[int, bytes] = {}
        #: The datagram's length, once its last fragment arrived.
        self.total: int | None = None

    def add(self, offset: int, data: bytes, last: bool) -> bytes | None:
        """Take one fragment; the datagram's bytes once every fragment is in."""
        self.parts[offset] = data
        if last:
            self.total = offset + len(data)
        total = self.total
        if total is None:
            return None
        out = bytearray(total)
        covered = 0
        for start in sorted(self.parts):
            if start > covered:
                return None  # a hole
            if start >= total:
                continue
            piece = self.parts[start][: total - start]
            out[start : start + len(piece)] = piece
            covered = max(covered, start + len(piece))
        return bytes(out) if covered >= total else None


class FrameDecoder:
    """Transport segments out of frames; keeps the IP fragments waiting for their datagram."""

    def __init__(self) -> None:
        self._fragments: OrderedDict[tuple[object, ...], _Fragments] = OrderedDict()
        #: Frames that held no IPv4 or IPv6 packet, or no TCP or UDP.
        self.skipped = 0

    def decode(
        self,
        data: bytes | mmap.mmap,
        start: int,
        end: int,
        linktype: int,
        length: int = 0,
    ) -> Segment | None:
        """The TCP segment or UDP datagram of the frame `data[start:end]`; None for a frame of
        anything else, or a fragment of a datagram not yet whole. FrameError when the headers
        are broken (offsets from the start of `data`)."""
        cut = length > end - start
        # The common case first, in one unpack: raw IPv4 of 20 header bytes and UDP.
        if linktype in (LINKTYPE_RAW, LINKTYPE_IPV4):
            ip = start
        elif linktype == LINKTYPE_ETHERNET:
            ip = self._ethernet(data, start, end)
            if ip < 0:
                return None
        else:
            ip = self._link(data, start, end, linktype)
            if ip < 0:
                return None
        if ip >= end:
            raise FrameError("the frame ends before its IP header", ip)
        version = data[ip] >> 4
        if version == 4:
            return self._ipv4(data, ip, end, cut)
        if version == 6:
            return self._ipv6(data, ip, end, cut)
        if linktype in (LINKTYPE_RAW, LINKTYPE_IPV4, LINKTYPE_IPV6):
            raise FrameError(f"IP version {version}, neither 4 nor 6", ip)
        self.skipped += 1
        return None

    # -- link layers ---------------------------------------------------------------------------

    def _ethernet(self, data: bytes | mmap.mmap, start: int, end: int) -> int:
        """Where the IP packet starts, or -1 for a frame of another protocol."""
        where = start + 12
        while True:
            if end - where < 2:
                raise FrameError("the frame ends inside its Ethernet header", start)
            (ethertype,) = _U16.unpack_from(data, where)
            if ethertype in _ETHERTYPE_VLAN:
                where += 4
                continue
            if ethertype in (_ETHERTYPE_IPV4, _ETHERTYPE_IPV6):
                return where + 2
            self.skipped += 1
            return -1

    def _link(self, data: bytes | mmap.mmap, start: int, end: int, linktype: int) -> int:
        if linktype == LINKTYPE_IPV6 or linktype in _DLT_RAW:
            return start
        if linktype == LINKTYPE_LINUX_SLL:
            if end - start < 16:
                raise FrameError("the frame ends inside its Linux cooked header", start)
            protocol = _U16.unpack_from(data, start + 14)[0]
            ip = start + 16
        elif linktype == LINKTYPE_LINUX_SLL2:
            if end - start < 20:
                raise FrameError("the frame ends inside its Linux cooked (v2) header", start)
            protocol = _U16.unpack_from(data, start)[0]
            ip = start + 20
        elif linktype in (LINKTYPE_NULL, LINKTYPE_LOOP):
            if end - start < 4:
                raise FrameError("the frame ends inside its loopback header", start)
            raw = bytes(data[start : start + 4])
            family = int.from_bytes(raw, "big")
            if linktype == LINKTYPE_NULL and family > 0xFFFF:
                family = int.from_bytes(raw, "little")  # the capturing machine's byte order
            protocol = (
                _ETHERTYPE_IPV4 if family == 2 else _ETHERTYPE_IPV6 if family in _AF_INET6 else 0
            )
            ip = start + 4
        else:
            raise FrameError(f"link type {linktype} is not one this reader knows", start)
        if protocol in (_ETHERTYPE_IPV4, _ETHERTYPE_IPV6):
            return ip
        self.skipped += 1
        return -1

    # -- IP ------------------------------------------------------------------------------------

    def _ipv4(self, data: bytes | mmap.mmap, ip: int, end: int, cut: bool) -> Segment | None:
        if end - ip >= 28 and data[ip] == 0x45 and data[ip + 9] == UDP:
            (_, _, total, _, fragment, _, _, _, source, destination, sport, dport, ulength) = (
                _IPV4_UDP.unpack_from(data, ip)
            )
            if not fragment & 0x3FFF and total >= 28 and 8 <= ulength <= total - 20:
                stop = ip + 20 + ulength
                if stop > end:
                    stop, cut = end, True
                return (
                    UDP,
                    source,
                    sport,
                    destination,
                    dport,
                    bytes(data[ip + 28 : stop]),
                    ip + 28,
                    0,
                    0,
                    cut,
                )
        if end - ip < 20:
            raise FrameError(f"IPv4 header cut short ({end - ip} of 20 bytes)", ip)
        first, _, total, ident, fragment, _, protocol, source, destination = _IPV4.unpack_from(
            data, ip
        )
        header = (first & 0x0F) * 4
        if header < 20:
            raise FrameError(f"IPv4 header length {header}, less than 20", ip)
        if total < header:
            raise FrameError(f"IPv4 total length {total}, less than its header's {header}", ip + 2)
        if end - ip < header:
            raise FrameError(f"IPv4 header cut short ({end - ip} of {header} bytes)", ip)
        stop = ip + total
        if stop > end:
            stop, cut = end, True
        if protocol != TCP and protocol != UDP:
            self.skipped += 1
            return None
        if fragment & 0x3FFF:
            payload = self._reassemble(
                (4, source, destination, ident, protocol),
                (fragment & 0x1FFF) * 8,
                bytes(data[ip + header : stop]),
                not fragment & 0x2000,
            )
            if payload is None:
                return None
            return self._transport(payload, 0, len(payload), protocol, source, destination, cut, ip)
        return self._transport(data, ip + header, stop, protocol, source, destination, cut)

    def _ipv6(self, data: bytes | mmap.mmap, ip: int, end: int, cut: bool) -> Segment | None:
        if end - ip < 40:
            raise FrameError(f"IPv6 header cut short ({end - ip} of 40 bytes)", ip)
        payload_length, next_header, _, source, destination = _IPV6.unpack_from(data, ip)
        stop = ip + 40 + payload_length
        if stop > end:
            stop, cut = end, True
        where = ip + 40
        fragment: tuple[int, int, bool] | None = None
        while next_header in _IPV6_EXTENSIONS or next_header in (_IPV6_FRAGMENT, _IPV6_AH):
            if stop - where < 8:
                raise FrameError("IPv6 extension header cut short", where)
            following, size = data[where], data[where + 1]
            if next_header == _IPV6_FRAGMENT:
                (field,) = _U16.unpack_from(data, where + 2)
                ident = int.from_bytes(data[where + 4 : where + 8], "big")
                fragment = (ident, field & 0xFFF8, not field & 1)
                size = 8
            elif next_header == _IPV6_AH:
                size = (size + 2) * 4
            else:
                size = (size + 1) * 8
            next_header = following
            where += size
        if where > stop:
            raise FrameError("IPv6 extension headers run past the packet", ip + 4)
        if next_header != TCP and next_header != UDP:
            self.skipped += 1
            return None
        if fragment is not None:
            ident, offset, last = fragment
            payload = self._reassemble(
                (6, source, destination, ident), offset, bytes(data[where:stop]), last
            )
            if payload is None:
                return None
            return self._transport(
                payload, 0, len(payload), next_header, source, destination, cut, ip
            )
        return self._transport(data, where, stop, next_header, source, destination, cut)

    def _reassemble(
        self, key: tuple[object, ...], offset: int, piece: bytes, last: bool
    ) -> bytes | None:
        fragments = self._fragments.get(key)
        if fragments is None:
            fragments = self._fragments[key] = _Fragments()
            if len(self._fragments) > MAX_REASSEMBLIES:
                self._fragments.popitem(last=False)
        whole = fragments.add(offset, piece, last)
        if whole is not None:
            del self._fragments[key]
        return whole

    # -- TCP and UDP ---------------------------------------------------------------------------

    @staticmethod
    def _transport(
        data: bytes | mmap.mmap,
        where: int,
        stop: int,
        protocol: int,
        source: bytes,
        destination: bytes,
        cut: bool,
        located: int | None = None,
    ) -> Segment:
        """The header at `data[where:stop]`. A datagram put together from fragments is not in
        the file in one piece: its errors are `located` at the IP header of its last fragment."""
        try:
            segment = FrameDecoder._header(data, where, stop, protocol, source, destination, cut)
        except FrameError as error:
            if located is None:
                raise
            raise FrameError(f"{error.reason} (in a reassembled datagram)", located) from None
        if located is not None:
            return (*segment[:6], -1, *segment[7:])
        return segment

    @staticmethod
    def _header(
        data: bytes | mmap.mmap,
        where: int,
        stop: int,
        protocol: int,
        source: bytes,
        destination: bytes,
        cut: bool,
    ) -> Segment:
        if protocol == UDP:
            if stop - where < 8:
                raise FrameError(f"UDP header cut short ({stop - where} of 8 bytes)", where)
            sport, dport, length = _UDP.unpack_from(data, where)
            if length < 8:
                raise FrameError(f"UDP length {length}, less than its header's 8", where + 4)
            if where + length > stop:
                if not cut:
                    raise FrameError(
                        f"UDP length {length} runs past the IP packet ({stop - where} bytes)",
                        where + 4,
                    )
            else:
                stop = where + length
            return (
                UDP,
                source,
                sport,
                destination,
                dport,
                bytes(data[where + 8 : stop]),
                where + 8,
                0,
                0,
                cut,
            )
        if stop - where < 20:
            raise FrameError(f"TCP header cut short ({stop - where} of 20 bytes)", where)
        sport, dport, sequence, _ack, offset, flags = _TCP.unpack_from(data, where)
        header = (offset >> 4) * 4
        if header < 20:
            raise FrameError(f"TCP header length {header}, less than 20", where + 12)
        if stop - where < header:
            raise FrameError(f"TCP header cut short ({stop - where} of {header} bytes)", where)
        return (
            TCP,
            source,
            sport,
            destination,
            dport,
            bytes(data[where + header : stop]),
            where + header,
            sequence,
            flags,
            cut,
        )


def address_text(address: bytes) -> str:
    """`192.0.2.7`, or `2001:db8::7`."""
    family = socket.AF_INET if len(address) == 4 else socket.AF_INET6
    return socket.inet_ntop(family, address)


def endpoint_text(address: bytes, port: int) -> str:
    """`192.0.2.7:7330`, or `[2001:db8::7]:7330`."""
    if len(address) == 4:
        return f"{address_text(address)}:{port}"
    return f"[{address_text(address)}]:{port}"
