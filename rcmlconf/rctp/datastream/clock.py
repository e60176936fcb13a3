"""NTP timestamps and the heartbeat clock estimator (D-RCTP-24).

A timestamp is RFC 5905's 64-bit format held as an int: seconds since 1900 in the high 32 bits, a
binary fraction of a second in the low 32. The seconds wrap every 2**32 s (an NTP era, the next in
2036), so a timestamp alone is ambiguous; as SNTP does (RFC 4330 §3), a timestamp whose top bit is
set is taken to be in era 0 (1968-2036) and one whose top bit is clear in era 1 (2036-2104).
Differences of timestamps are taken modulo 2**64 and read as signed (RFC 5905 §6), so they are
right across an era's end.

The caller passes its `now` in as Unix seconds; nothing here reads a clock.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

from rcmlconf.errors import EncodeError

#: Seconds from 1900-01-01 (NTP's epoch) to 1970-01-01 (Unix's).
NTP_UNIX_OFFSET = 2_208_988_800
_ONE = 1 << 32
_MOD = 1 << 64
_HALF = 1 << 63
#: The Unix seconds the era rule maps timestamps to: [1968-01-20T03:14:08Z, 2104-02-26T09:42:24Z).
UNIX_MIN = (1 << 31) - NTP_UNIX_OFFSET
UNIX_END = (1 << 32) + (1 << 31) - NTP_UNIX_OFFSET
#: D-RCTP-24: the clock filter's memory, as NTP's.
SAMPLES = 8


def ntp_from_unix(seconds: float) -> int:
    """The NTP timestamp of a Unix time, to the nearest 2**-32 s."""
    if not UNIX_MIN <= seconds < UNIX_END:
        raise EncodeError(f"Unix time {seconds} is outside the NTP eras 0 and 1 can tell apart")
    whole = math.floor(seconds)
    # Split before scaling: seconds + NTP_UNIX_OFFSET as a float would lose a bit of fraction.
    fraction = round((seconds - whole) * _ONE)
    return (((whole + NTP_UNIX_OFFSET) << 32) + fraction) % _MOD


def unix_from_ntp(timestamp: int) -> float:
    """The Unix time of an NTP timestamp, by the era rule above."""
    era = 0 if timestamp & _HALF else 1
    # Whole seconds as ints, so that one rounding (the sum's) is all the fraction suffers.
    seconds = (timestamp >> 32) + (era << 32) - NTP_UNIX_OFFSET
    return seconds + (timestamp & (_ONE - 1)) / _ONE


def ntp_difference(later: int, earlier: int) -> float:
    """`later - earlier` in seconds, right across an era's end (RFC 5905 §6)."""
    return (((later - earlier + _HALF) % _MOD) - _HALF) / _ONE


@dataclass(frozen=True, slots=True)
class ClockSample:
    """One heartbeat's view of the peer's clock: θ and δ of D-RCTP-24, in seconds."""

    #: θ: the peer's (robot's) clock minus ours.
    offset: float
    #: δ: the round trip, without the time the peer took to answer.
    delay: float

    @classmethod
    def from_times(cls, t1: int, t2: int, t3: int, t4: int) -> ClockSample:
        """T1 request sent and T4 ACK arrived, by our clock; T2 request arrived and T3 ACK sent,
        by the peer's (a `HeartbeatAck` carries T1 to T3; T4 is the caller's `now`).
        """
        return cls(
            offset=(ntp_difference(t2, t1) + ntp_difference(t3, t4)) / 2,
            delay=ntp_difference(t4, t1) - ntp_difference(t3, t2),
        )


@dataclass(frozen=True, slots=True)
class ClockEstimate:
    """The peer's clock minus ours, give or take `uncertainty` seconds."""

    offset: float
    #: δ of the sample the estimate comes from.
    delay: float
    #: δ/2 + the peer's time precision (D-RCTP-24): never better than the peer's own precision.
    uncertainty: float
    #: How many samples it was chosen from (at most 8).
    samples: int


class ClockEstimator:
    """NTP's clock filter over heartbeats (D-RCTP-24): of the last 8 samples, the one with the
    smallest round trip, since the true offset lies within δ/2 of any sample's θ and a short round
    trip leaves the least room for asymmetric delays.
    """

    __slots__ = ("_precision", "_samples")

    def __init__(self, precision: float = 0.0) -> None:
        """`precision`: the robot's `timePrecision` in seconds (D-RCML-17), 0 when unknown."""
        if not (precision >= 0 and math.isfinite(precision)):
            raise ValueError(f"time precision {precision} is not a finite number >= 0")
        self._precision = precision
        self._samples: deque[ClockSample] = deque(maxlen=SAMPLES)

    def add(self, sample: ClockSample) -> ClockEstimate:
        """Take one heartbeat's sample and give the estimate it leads to."""
        self._samples.append(sample)
        estimate = self.estimate
        assert estimate is not None  # a sample was just added
        return estimate

    @property
    def estimate(self) -> ClockEstimate | None:
        """The current estimate; None before the first sample."""
        if not self._samples:
            return None
        # Newest first, so that of equal round trips the freshest offset wins.
        best = min(reversed(self._samples), key=lambda sample: sample.delay)
        # A negative δ (the peer's clock ran faster than ours during the exchange, or its
        # timestamps are wrong) cannot bound anything below zero: it counts as 0.
        delay = max(best.delay, 0.0)
        return ClockEstimate(
            best.offset, best.delay, delay / 2 + self._precision, len(self._samples)
        )
