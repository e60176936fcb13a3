"""The receiver's sequence rules (D-RCTP-21): newer, duplicate or late, and what was lost.

Sequence numbers are 16-bit and wrap (D-RCTP-19). Following RFC 1982 serial arithmetic, a number
is newer than the highest seen when it is ahead by 1 to 32,767 modulo 65,536; one behind by 0 to
32,768 is not newer: a duplicate when it was received before, late otherwise. Only a newer packet's
DATA payloads are applied (R-RCTP-43).

The tracker also unwraps numbers into an unbounded count (as RTP's extended sequence number does,
RFC 3550 appendix A.1), so that "lost" is plain arithmetic: every number a newer packet skips past
counts as lost until it arrives late.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

_MODULO = 1 << 16
_MASK = _MODULO - 1
#: The largest step that is still ahead (RFC 1982 with SERIAL_BITS 16: 2**15 - 1).
_MAX_AHEAD = (1 << 15) - 1
_CLEAR = bytes(_MAX_AHEAD)


class Arrival(enum.Enum):
    NEWER = "newer"
    DUPLICATE = "duplicate"
    LATE = "late"


_NEWER = Arrival.NEWER


@dataclass(frozen=True, slots=True)
class SequenceCounts:
    #: Every packet given to the tracker: newer + duplicates + late.
    received: int
    newer: int
    duplicates: int
    #: Received for the first time but not newer: reordered, or from before the first packet.
    late: int
    #: Numbers skipped by a newer packet that have not arrived since.
    lost: int


class SequenceTracker:
    """The sequence state of one peer's packets. Pure state: no clock, no I/O."""

    __slots__ = (
        "_duplicates",
        "_first",
        "_gaps",
        "_highest",
        "_largest_gap",
        "_late",
        "_lost",
        "_newer",
        "_next",
        "_seen",
    )

    def __init__(self) -> None:
        #: One flag per 16-bit number: received since the highest passed it. Only numbers in
        #: the window behind the highest (0 to 32,768) are ever asked about, and each of those was
        #: cleared or set when the highest last passed it, so stale flags are never read.
        self._seen = bytearray(_MODULO)
        #: Unwrapped numbers of the first packet and the highest so far; None before the first.
        self._first: int | None = None
        self._highest = 0
        #: The number after the highest, which nearly every packet has; None before the first.
        self._next: int | None = None
        self._newer = self._duplicates = self._late = self._lost = 0
        self._gaps = self._largest_gap = 0

    @property
    def highest(self) -> int | None:
        """The highest sequence number seen (16-bit), None before the first packet."""
        return None if self._first is None else self._highest & _MASK

    @property
    def gaps(self) -> tuple[int, int]:
        """Times a newer packet skipped numbers, and the most one skipped at once."""
        return self._gaps, self._largest_gap

    @property
    def counts(self) -> SequenceCounts:
        received = self._newer + self._duplicates + self._late
        return SequenceCounts(received, self._newer, self._duplicates, self._late, self._lost)

    def extended(self, sequence: int) -> int:
        """The unbounded number a 16-bit sequence number stands for, judged from the highest seen:
        the nearest one, as SRTP estimates its packet index (RFC 3711 §3.3.1). Before the first
        packet, the number itself. Changes nothing: a receiver asks before it authenticates."""
        if self._first is None:
            return sequence
        ahead = (sequence - self._highest) & _MASK
        return self._highest + ahead if ahead <= _MAX_AHEAD else self._highest - (_MODULO - ahead)

    def replayed(self, sequence: int, window: int) -> bool:
        """Whether a packet is to be dropped unread: seen before, or more than `window` behind
        the highest (SRTP's replay list, RFC 3711 §3.3.2; D-RSP-15). Changes nothing: a receiver
        asks before it authenticates, and only an authentic packet may move the window."""
        if self._first is None:
            return False
        ahead = (sequence - self._highest) & _MASK
        if 1 <= ahead <= _MAX_AHEAD:
            return False
        return (_MODULO - ahead) % _MODULO > window or bool(self._seen[sequence])

    def see(self, sequence: int) -> Arrival:
        """Take one packet's sequence number and say what it is (D-RCTP-21)."""
        if sequence == self._next:
            # `_advance(1)` without the call or the flags to clear: a receiver takes one packet
            # each period, `rcmlconf dissect` a million of a capture.
            self._next = (sequence + 1) & _MASK
            self._highest += 1
            self._seen[sequence] = 1
            self._newer += 1
            return _NEWER
        if not 0 <= sequence <= _MASK:
            raise ValueError(f"sequence number {sequence} is not 16-bit")
        if self._first is None:  # D-RCTP-21: the first packet is newer by definition
            self._first = self._highest = sequence
            self._next = (sequence + 1) & _MASK
            self._seen[sequence] = 1
            self._newer += 1
            return _NEWER
        highest = self._highest
        ahead = (sequence - highest) & _MASK
        if 1 <= ahead <= _MAX_AHEAD:  # D-RCTP-21, RFC 1982
            self._advance(ahead)
            return _NEWER
        if self._seen[sequence]:
            self._duplicates += 1
            return Arrival.DUPLICATE
        self._seen[sequence] = 1
        self._late += 1
        # Behind by 1 to 32,768. A number after the first was skipped by a newer packet and
        # counted lost; one before the first never was.
        if highest - (_MODULO - ahead) > self._first:
            self._lost -= 1
        return Arrival.LATE

    def _advance(self, ahead: int) -> None:
        """Move the highest `ahead` numbers on; the ones passed over are lost until they arrive."""
        skipped = ahead - 1
        start = (self._highest + 1) & _MASK
        end = start + skipped
        # The passed-over numbers' flags belong to numbers 65,536 older: clear them.
        if end <= _MODULO:
            self._seen[start:end] = _CLEAR[:skipped]
        else:
            self._seen[start:] = _CLEAR[: _MODULO - start]
            self._seen[: end - _MODULO] = _CLEAR[: end - _MODULO]
        self._highest += ahead
        self._next = (self._highest + 1) & _MASK
        self._seen[self._highest & _MASK] = 1
        self._newer += 1
        self._lost += skipped
        if skipped:
            self._gaps += 1
            self._largest_gap = max(self._largest_gap, skipped)
