"""The IPv4/IPv6, TCP and UDP headers of a capture's frames.

`FrameDecoder.decode(...)` reads a frame's link layer (Ethernet with VLAN tags, raw IP, Linux
cooked SLL and SLL2, BSD loopback/NULL), IPv4 (fragments reassembled) or IPv6 (extension headers
skipped, fragments reassembled), and TCP or UDP, and returns the transport's fields and payload
(a `Segment`). Broken headers are a `FrameError` at their offset in the file: the records after
the frame are still readable.
"""

from __future__ import annotations

import mmap
import struct
from typing import Final

from rcmlconf.pcap.fragments import Reassembly
from rcmlconf.pcap.records import FrameError

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


class FrameDecoder:
    """Transport segments out of frames; keeps the IP fragments waiting for their datagram."""

    def __init__(self) -> None:
        self._reassembly = Reassembly()
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
            known = ", ".join(f"{number} ({name})" for number, name in sorted(LINK_TYPES.items()))
            raise FrameError(f"link type {linktype} is none this reader knows: {known}", start)
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
            payload = self._reassembly.add(
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
            payload = self._reassembly.add(
                (6, source, destination, ident), offset, bytes(data[where:stop]), last
            )
            if payload is None:
                return None
            return self._transport(
                payload, 0, len(payload), next_header, source, destination, cut, ip
            )
        return self._transport(data, where, stop, next_header, source, destination, cut)

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
