"""TCP reassembly of one direction of a connection, by sequence number.

Bytes come out in stream order, each once: a segment that repeats bytes already delivered is a
retransmission (its new bytes, if any, are delivered), one that comes before the bytes it follows
waits until they arrive (out of order). A hole the capture never fills (the capture lost the
segment, or started late) is given up on when the waiting bytes pass `MAX_WAITING`, or at the end,
and reported: the bytes after it cannot be framed by what came before.
"""

from __future__ import annotations

from typing import Final

#: A piece of the stream: (stream offset, bytes, frame, time, file offset of its first byte or -1).
Piece = tuple[int, bytes, int, float, int]

SYN: Final = 0x02
FIN: Final = 0x01
RST: Final = 0x04
ACK: Final = 0x10
_MASK = 0xFFFFFFFF
_HALF = 1 << 31
#: Bytes held out of order, at most, before the hole in front of them is given up on.
MAX_WAITING = 4 * 1024 * 1024


class TcpStream:
    """One direction's bytes. `position` is the stream offset of the next byte expected."""

    __slots__ = (
        "_next",
        "bytes",
        "finished",
        "from_start",
        "holes",
        "out_of_order",
        "position",
        "retransmissions",
        "segments",
        "skipped",
        "started",
        "waiting",
        "waiting_bytes",
    )

    def __init__(self) -> None:
        #: The sequence number of the next byte expected (32-bit).
        self._next = 0
        self.position = 0
        self.started = False
        #: The handshake was seen: the stream is whole from its first byte.
        self.from_start = False
        #: Segments waiting for the bytes before them: stream offset -> piece.
        self.waiting: dict[int, Piece] = {}
        self.waiting_bytes = 0
        self.segments = 0
        self.bytes = 0
        self.retransmissions = 0
        self.out_of_order = 0
        #: Holes given up on, and the bytes they lost.
        self.holes = 0
        self.skipped = 0
        self.finished = False

    def segment(
        self, sequence: int, flags: int, payload: bytes, frame: int, time: float, where: int
    ) -> list[Piece]:
        """Take one segment (`where`: its payload's offset in the file, or -1); the pieces now
        in order, oldest first."""
        if flags & SYN:
            if not self.started:
                self._next = (sequence + 1) & _MASK
                self.started = True
                self.from_start = True
            if not payload:
                return []
            # Data on a SYN (TCP Fast Open, RFC 7413) starts after the SYN's sequence number.
            sequence = (sequence + 1) & _MASK
        elif not self.started:
            # The capture began after the handshake: the stream starts here.
            self._next = sequence
            self.started = True
        if not payload:
            if flags & (FIN | RST):
                self.finished = True
            return []
        self.segments += 1
        ahead = ((sequence - self._next + _HALF) & _MASK) - _HALF
        size = len(payload)
        if ahead + size <= 0:
            self.retransmissions += 1
            return []
        if ahead < 0:
            self.retransmissions += 1
            payload = payload[-ahead:]
            if where >= 0:
                where -= ahead
            ahead = 0
        if ahead > 0:
            at = self.position + ahead
            held = self.waiting.get(at)
            if held is not None and len(held[1]) >= size:
                self.retransmissions += 1
                return []
            self.out_of_order += 1
            self.waiting[at] = (at, payload, frame, time, where)
            self.waiting_bytes += size - (len(held[1]) if held is not None else 0)
            if self.waiting_bytes > MAX_WAITING:
                return self.give_up()
            return []
        out: list[Piece] = [(self.position, payload, frame, time, where)]
        self._advance(len(payload))
        if self.waiting:
            self._drain(out)
        if flags & (FIN | RST):
            self.finished = True
        return out

    def _advance(self, count: int) -> None:
        self.position += count
        self.bytes += count
        self._next = (self._next + count) & _MASK

    def _drain(self, out: list[Piece]) -> None:
        """Deliver what waited and now follows on."""
        waiting = self.waiting
        while waiting:
            first = min(waiting)
            if first > self.position:
                return
            _, payload, frame, time, where = waiting.pop(first)
            self.waiting_bytes -= len(payload)
            overlap = self.position - first
            if overlap >= len(payload):
                self.retransmissions += 1
                continue
            if overlap:
                payload = payload[overlap:]
                if where >= 0:
                    where += overlap
            out.append((self.position, payload, frame, time, where))
            self._advance(len(payload))

    def give_up(self) -> list[Piece]:
        """Skip the hole before the oldest waiting segment: what follows it comes out, its
        first piece marking where the hole was."""
        if not self.waiting:
            return []
        first = min(self.waiting)
        lost = first - self.position
        self.holes += 1
        self.skipped += lost
        self.position = first
        self._next = (self._next + lost) & _MASK
        out: list[Piece] = []
        self._drain(out)
        return out
