"""Classic pcap: the 24-byte file header and its packet records, in both byte orders, with
microsecond and nanosecond stamps; one link type for the whole file."""

from __future__ import annotations

import mmap
import struct
from collections.abc import Iterator

from rcmlconf.pcap.records import CaptureError, Record
from rcmlconf.wording import plural

MAGIC = {
    # magic as read little-endian -> (byte order, seconds per stamp unit)
    0xA1B2C3D4: ("<", 1e-6),
    0xD4C3B2A1: (">", 1e-6),
    0xA1B23C4D: ("<", 1e-9),
    0x4D3CB2A1: (">", 1e-9),
}
HEADER_SIZE = 24


def decimals(data: bytes | mmap.mmap) -> int:
    """Decimals of a second the stamps have: 6 (microseconds) or 9 (nanoseconds)."""
    return 6 if MAGIC[struct.unpack_from("<I", data, 0)[0]][1] == 1e-6 else 9


def records(data: bytes | mmap.mmap) -> Iterator[Record]:
    """Every packet record in file order; CaptureError where the structure breaks."""
    (magic,) = struct.unpack_from("<I", data, 0)
    order, unit = MAGIC[magic]
    major, _minor, _zone, _figures, _snap, network = struct.unpack_from(order + "HHiIII", data, 4)
    if major != 2:
        raise CaptureError(f"pcap version {major}, not 2", 4)
    linktype = network & 0xFFFF
    unpack = struct.Struct(order + "IIII").unpack_from
    size = len(data)
    offset = HEADER_SIZE
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
