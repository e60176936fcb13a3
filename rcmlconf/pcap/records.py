"""What reading a capture gives: a packet `Record`, or the place where the file or a frame breaks.

The only exception the readers (`reader`, `classic`, `pcapng`) and the frame decoder (`frames`)
let escape is `CaptureError`, a `ProtocolError` whose offset counts bytes from the start of the
file: the file's structure is broken there (`Capture.records`), or a frame's headers are
(`FrameDecoder.decode`, a `FrameError`: the records after it are still readable).
"""

from __future__ import annotations

from rcmlconf.errors import ProtocolError

#: A packet record: time (Unix seconds), link type, the frame's start and end in `Capture.data`,
#: and its length on the wire.
Record = tuple[float, int, int, int, int]


class CaptureError(ProtocolError):
    """A capture file, or a frame in it, that cannot be read; `offset` counts from the file's
    start."""


class FrameError(CaptureError):
    """One frame's link, IP or transport header is broken; the records after it can be read."""
