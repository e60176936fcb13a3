"""The clocks of a session (D-RSP-13): a beat every period T, and what silence from the peer means.

Both are pure: time comes in as `now`, and each says when it next needs to be asked (`deadline`).
"""

from __future__ import annotations

import enum

#: D-RSP-13: silence for this many periods means the link is lost ...
LOST_PERIODS = 25
#: ... and for this many seconds ends the session.
SESSION_TIMEOUT = 10.0
#: D-RSP-13: a side with no bit to set sends an empty Device Map this many periods apart.
KEEPALIVE_PERIODS = 5


class Beat:
    """A packet every period: `due` says whether one is due now and moves to the next. A beat
    missed by more than a period (the process was held up) is not made up with a burst."""

    __slots__ = ("idle", "next", "period")

    def __init__(self, period: float, start: float) -> None:
        self.period = period
        self.next = start
        #: Beats since a packet was last sent, for the keep-alive.
        self.idle = 0

    def due(self, now: float) -> bool:
        if now < self.next:
            return False
        self.next += self.period
        if self.next <= now:
            self.next = now + self.period
        return True

    def quiet(self) -> bool:
        """This beat had nothing to send: whether the keep-alive is due instead."""
        self.idle += 1
        return self.idle >= KEEPALIVE_PERIODS

    def sent(self) -> None:
        self.idle = 0


class Silence(enum.Enum):
    LOST = "lost"
    TIMEOUT = "timeout"


class Liveness:
    """How long the peer has been silent (D-RSP-13)."""

    __slots__ = ("last_heard", "lost", "period")

    def __init__(self, period: float, now: float) -> None:
        self.period = period
        self.last_heard = now
        self.lost = False

    def heard(self, now: float) -> bool:
        """A packet came; whether it ends a lost link."""
        self.last_heard = now
        restored, self.lost = self.lost, False
        return restored

    def check(self, now: float) -> Silence | None:
        """What the silence until `now` newly means, once each."""
        if now >= self.last_heard + SESSION_TIMEOUT:
            return Silence.TIMEOUT
        if not self.lost and now >= self.last_heard + LOST_PERIODS * self.period:
            self.lost = True
            return Silence.LOST
        return None

    def deadline(self) -> float:
        if self.lost:
            return self.last_heard + SESSION_TIMEOUT
        return min(self.last_heard + LOST_PERIODS * self.period, self.last_heard + SESSION_TIMEOUT)
