"""pcapng: Section Header, Interface Description, Enhanced, Simple and the obsolete Packet
blocks, each interface with its own link type, `if_tsresol` and `if_tsoffset`, sections in either
byte order. Any other block (name resolution, statistics, secrets, custom) is skipped."""

from __future__ import annotations

import mmap
import struct
from collections.abc import Iterator

from rcmlconf.pcap.records import CaptureError, Record
from rcmlconf.wording import plural

#: The block type of a Section Header Block, which starts every pcapng file.
SECTION_HEADER = 0x0A0D0D0A
_IDB = 1
_OPB = 2
_SPB = 3
_EPB = 6
_BYTE_ORDER_MAGIC = 0x1A2B3C4D
#: pcapng's option codes of an Interface Description Block.
_OPT_END, _OPT_TSRESOL, _OPT_TSOFFSET = 0, 9, 14


def decimals(data: bytes | mmap.mmap) -> int:
    """Decimals of a second the stamps have: 6 (microseconds) or 9 (nanoseconds), the finest of
    the interfaces described before the first packet."""
    divisors = [1_000_000]
    try:
        for block in _interfaces(data):
            divisors.append(block)
    except CaptureError:
        pass
    finest = max(divisors)
    return 6 if finest <= 1_000_000 else 9


class _Interface:
    __slots__ = ("divisor", "linktype", "offset", "snaplen")

    def __init__(self, linktype: int, snaplen: int, divisor: int, offset: int) -> None:
        self.linktype = linktype
        self.snaplen = snaplen
        #: Stamp units per second (if_tsresol) and seconds to add (if_tsoffset).
        self.divisor = divisor
        self.offset = offset


def records(data: bytes | mmap.mmap) -> Iterator[Record]:
    """Every packet record in file order; CaptureError where the structure breaks."""
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
        if struct.unpack_from("<I", data, offset)[0] == SECTION_HEADER:
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
        elif kind == SECTION_HEADER:
            if total < 28:
                raise CaptureError(f"Section Header Block of {total} bytes, fewer than 28", offset)
            (major,) = struct.unpack_from(order + "H", data, body + 4)
            if major != 1:
                raise CaptureError(f"pcapng version {major}, not 1", body + 4)
        # Any other block (name resolution, statistics, secrets, custom) is skipped.
        offset = end


def _interfaces(data: bytes | mmap.mmap) -> Iterator[int]:
    """The stamp units per second of each interface described before the first packet."""
    size = len(data)
    offset = 0
    order = "<"
    while size - offset >= 12:
        if struct.unpack_from("<I", data, offset)[0] == SECTION_HEADER:
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
