"""Read pcap and pcapng captures: `Capture`, the packet records of one file.

Built for speed with `struct` over the file's bytes (a memory map, or bytes): no object per record
but a tuple, and no copy of a frame until its transport payload is sliced out.

- `Capture.records()` yields `(time, linktype, start, end, length)` for each packet record (a
  `records.Record`): the frame is `capture.data[start:end]`, `length` its length on the wire
  (more than `end - start` when the snap length cut it). `Capture.frames()` yields
  `(time, linktype, frame)`.
- Formats: classic pcap (`classic`) and pcapng (`pcapng`), told apart by their magic numbers.
- A frame's link, IP and transport headers are `frames.FrameDecoder`'s.

The only exception a capture lets escape is `records.CaptureError`, whose offset counts bytes from
the start of the file: the file's structure is broken there.
"""

from __future__ import annotations

import mmap
import os
import stat
import struct
from collections.abc import Iterator
from pathlib import Path
from types import TracebackType
from typing import BinaryIO, Final

from rcmlconf.pcap import classic, pcapng
from rcmlconf.pcap.records import CaptureError, Record
from rcmlconf.wording import plural

#: What a capture read from a pipe or a device may hold (in memory); a file is mapped instead.
MAX_STREAM: Final = 1 << 30
_CHUNK = 1 << 20


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
        head = stream.read(classic.HEADER_SIZE)
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
            return classic.decimals(self.data)
        return pcapng.decimals(self.data)

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
            return classic.records(self.data)
        return pcapng.records(self.data)

    def frames(self) -> Iterator[tuple[float, int, bytes]]:
        """`(time, linktype, frame bytes)` of every packet record."""
        data = self.data
        for time, linktype, start, end, _ in self.records():
            yield time, linktype, bytes(data[start:end])


def _detect(data: bytes | mmap.mmap) -> str:
    if len(data) < 4:
        raise CaptureError(f"{plural(len(data), 'byte')}: too short for a pcap or pcapng file", 0)
    (magic,) = struct.unpack_from("<I", data, 0)
    if magic in classic.MAGIC:
        if len(data) < classic.HEADER_SIZE:
            raise CaptureError(
                f"pcap file header of {len(data)} bytes, not {classic.HEADER_SIZE}", len(data)
            )
        return "pcap"
    if magic == pcapng.SECTION_HEADER:
        return "pcapng"
    raise CaptureError(
        f"not a pcap or pcapng file (it starts with {bytes(data[:4]).hex()},"
        " no capture format's magic number)",
        0,
    )
