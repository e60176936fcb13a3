"""What the analysis keeps of one sender's packets in one session: a *stream*.

Per stream: packets and bytes, the sequence rules of D-RCTP-21 and D-RSP-15 (newer, late,
duplicate, lost: `SequenceTracker`'s, counted inline with a shortcut for the packet that is the
next one, which nearly every packet is; tests/dissect check that the counts are the core
tracker's on any sequence), sequence gaps, inter-arrival times and RFC 3550's jitter estimator,
which takes each packet's arrival (the capture's stamp) and its sender's timestamp:

    D(i-1, i) = (R_i - R_{i-1}) - (S_i - S_{i-1});   J += (|D| - J) / 16

A stream keeps a time series (arrival, inter-arrival, transit) only when asked to (`--plot`).
"""

from __future__ import annotations

from array import array
from dataclasses import dataclass

_MODULO = 1 << 16
_MASK = _MODULO - 1
#: RFC 1982 with 16 bits: the largest step that is still ahead.
_MAX_AHEAD = (1 << 15) - 1
_CLEAR = bytes(_MAX_AHEAD)


@dataclass(frozen=True, slots=True)
class StreamReport:
    """A stream's figures, for the analysis (`Stream.report`)."""

    protocol: str
    source: str
    destination: str
    #: The session: the data stream's tag (8 hex digits) or RSP's session ID (12 hex digits).
    session: str
    label: str
    packets: int
    bytes: int
    first: float
    last: float
    lost: int
    late: int
    duplicates: int
    #: Times a newer packet skipped numbers, and the most it skipped at once.
    gaps: int
    largest_gap: int
    #: RFC 3550's interarrival jitter, seconds.
    jitter: float
    #: Inter-arrival times, seconds.
    interarrival_mean: float | None
    interarrival_max: float | None
    #: The rule the sequence numbers answer to.
    rule: str


class Stream:
    __slots__ = (
        "_arrival",
        "_first",
        "_highest",
        "_seen",
        "_stamp",
        "bytes",
        "destination",
        "duplicates",
        "first",
        "gaps",
        "jitter",
        "label",
        "largest_gap",
        "largest_interarrival",
        "late",
        "lost",
        "newer",
        "packets",
        "protocol",
        "rule",
        "series",
        "session",
        "source",
    )

    def __init__(
        self,
        protocol: str,
        source: str,
        destination: str,
        session: str,
        rule: str,
        series: bool,
    ) -> None:
        self.protocol = protocol
        self.source = source
        self.destination = destination
        self.session = session
        self.rule = rule
        self.label = ""
        self.packets = 0
        self.bytes = 0
        self.first = 0.0
        self._arrival = 0.0
        self._stamp = 0.0
        #: As `SequenceTracker`: a flag per 16-bit number (received since the highest passed
        #: it), and the unwrapped numbers of the first packet and of the highest (-1: none yet).
        self._seen = bytearray(_MODULO)
        self._first = -1
        self._highest = -1
        self.newer = self.duplicates = self.late = self.lost = 0
        self.gaps = 0
        self.largest_gap = 0
        self.jitter = 0.0
        self.largest_interarrival = 0.0
        #: (arrival, inter-arrival, transit) of each packet after the first, for --plot.
        self.series: tuple[array[float], array[float], array[float]] | None = (
            (array("d"), array("d"), array("d")) if series else None
        )

    def see(self, time: float, sequence: int, stamp: float, size: int) -> None:
        """One packet: its arrival, sequence number, sender's timestamp (seconds) and size."""
        self.bytes += size
        if self.packets:
            interarrival = time - self._arrival
            difference = interarrival - (stamp - self._stamp)
            self.jitter += ((difference if difference >= 0 else -difference) - self.jitter) / 16
            if interarrival > self.largest_interarrival:
                self.largest_interarrival = interarrival
            if self.series is not None:
                times, gaps, transits = self.series
                times.append(time)
                gaps.append(interarrival)
                transits.append(time - stamp)
            highest = self._highest
            ahead = (sequence - highest) & _MASK
            if ahead == 1:
                self._highest = highest + 1
                self._seen[sequence] = 1
                self.newer += 1
            else:
                self._sequence(sequence, ahead)
        else:
            self.first = time
            self._first = self._highest = sequence
            self._seen[sequence] = 1
            self.newer += 1
        self.packets += 1
        self._arrival = time
        self._stamp = stamp

    def _sequence(self, sequence: int, ahead: int) -> None:
        """D-RCTP-21 for a packet that is not the next one (`SequenceTracker.see`)."""
        seen = self._seen
        if 1 <= ahead <= _MAX_AHEAD:
            skipped = ahead - 1
            start = (self._highest + 1) & _MASK
            end = start + skipped
            if end <= _MODULO:
                seen[start:end] = _CLEAR[:skipped]
            else:
                seen[start:] = _CLEAR[: _MODULO - start]
                seen[: end - _MODULO] = _CLEAR[: end - _MODULO]
            self._highest += ahead
            seen[sequence] = 1
            self.newer += 1
            self.lost += skipped
            self.gaps += 1
            if skipped > self.largest_gap:
                self.largest_gap = skipped
        elif seen[sequence]:
            self.duplicates += 1
        else:
            seen[sequence] = 1
            self.late += 1
            if self._highest - (_MODULO - ahead) > self._first:
                self.lost -= 1

    @property
    def last(self) -> float:
        """When the newest packet arrived."""
        return self._arrival

    def report(self) -> StreamReport:
        span = self._arrival - self.first
        return StreamReport(
            self.protocol,
            self.source,
            self.destination,
            self.session,
            self.label,
            self.packets,
            self.bytes,
            self.first,
            self._arrival,
            self.lost,
            self.late,
            self.duplicates,
            self.gaps,
            self.largest_gap,
            self.jitter,
            span / (self.packets - 1) if self.packets > 1 else None,
            self.largest_interarrival if self.packets > 1 else None,
            self.rule,
        )
