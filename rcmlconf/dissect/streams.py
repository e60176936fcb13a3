"""What the analysis keeps of one sender's packets in one session: a *stream*.

Per stream: packets and bytes, the sequence rules of D-RCTP-21 and D-RSP-15 (newer, late,
duplicate, lost and gaps: the core's `SequenceTracker`, as a receiver counts them), inter-arrival
times and RFC 3550's jitter estimator, which takes each packet's arrival (the capture's stamp) and
its sender's timestamp:

    D(i-1, i) = (R_i - R_{i-1}) - (S_i - S_{i-1});   J += (|D| - J) / 16

A stream keeps a time series (arrival, inter-arrival, transit) only when asked to (`--plot`).
"""

from __future__ import annotations

from array import array
from dataclasses import dataclass

from rcmlconf.rctp.datastream.order import SequenceTracker


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
        "_stamp",
        "_track",
        "bytes",
        "destination",
        "first",
        "jitter",
        "label",
        "largest_interarrival",
        "packets",
        "protocol",
        "rule",
        "sequences",
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
        self.sequences = SequenceTracker()
        self._track = self.sequences.see  # bound once: `see` runs for every packet
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
        else:
            self.first = time
        self._track(sequence)
        self.packets += 1
        self._arrival = time
        self._stamp = stamp

    @property
    def last(self) -> float:
        """When the newest packet arrived."""
        return self._arrival

    def report(self) -> StreamReport:
        span = self._arrival - self.first
        counts = self.sequences.counts
        gaps, largest_gap = self.sequences.gaps
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
            counts.lost,
            counts.late,
            counts.duplicates,
            gaps,
            largest_gap,
            self.jitter,
            span / (self.packets - 1) if self.packets > 1 else None,
            self.largest_interarrival if self.packets > 1 else None,
            self.rule,
        )
