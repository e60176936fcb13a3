"""The audio processor (D-RSP-22), without I/O: sound as numbered fragments, played in order.

"The Audio processor plays multimedia data fragmented into pieces of small size" (paper §II.B).
A sender cuts a sound into fragments no larger than its device's `samples` field and numbers them;
a receiver plays them in order, drops one that comes after a newer one was played (a late fragment
cannot be played in its place any more), and counts the numbers it never got (R-RSP-39).
"""

from __future__ import annotations

from dataclasses import dataclass

_MODULO = 1 << 16
_HALF = 1 << 15


class FragmentSender:
    """Numbers a sound's fragments 0, 1, 2, ... modulo 65,536."""

    def __init__(self, fragment_size: int) -> None:
        if fragment_size < 1:
            raise ValueError("a fragment holds at least one byte")
        self.fragment_size = fragment_size
        self._next = 0
        self._pending = bytearray()

    def feed(self, samples: bytes) -> list[tuple[int, bytes]]:
        """Whole fragments of what was fed so far, numbered; the rest waits for more."""
        self._pending += samples
        size = self.fragment_size
        whole = len(self._pending) // size * size
        fragments = []
        for start in range(0, whole, size):
            fragments.append((self._next, bytes(self._pending[start : start + size])))
            self._next = (self._next + 1) % _MODULO
        del self._pending[:whole]
        return fragments

    def flush(self) -> list[tuple[int, bytes]]:
        """The last, shorter fragment."""
        if not self._pending:
            return []
        fragment = (self._next, bytes(self._pending))
        self._next = (self._next + 1) % _MODULO
        self._pending.clear()
        return [fragment]


@dataclass(slots=True)
class AudioCounts:
    played: int = 0
    #: Numbers skipped by a played fragment and never played.
    gaps: int = 0
    #: Arrived after a newer one was played: dropped.
    late: int = 0
    duplicates: int = 0


class AudioReceiver:
    """Plays fragments in order and counts what went missing."""

    def __init__(self) -> None:
        self._last: int | None = None
        self.counts = AudioCounts()
        self.sound = bytearray()

    def receive(self, fragment: int, samples: bytes) -> bool:
        """Whether the fragment was played (appended to `sound`)."""
        if self._last is not None:
            ahead = (fragment - self._last) % _MODULO
            if ahead == 0:
                self.counts.duplicates += 1
                return False
            if ahead >= _HALF:
                self.counts.late += 1
                return False
            self.counts.gaps += ahead - 1
        self._last = fragment
        self.counts.played += 1
        self.sound += samples
        return True
