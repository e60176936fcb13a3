"""How late the harness's own event loop ran during a case.

A timing check (packets T apart, a repeat after 250 ms) reads arrival times off the harness's
event loop. When that loop is held up (a loaded CI machine, a collection pause; with the embedded
reference, the target's timers too), datagrams are read late and the gaps between them are the
harness's, not the target's. `LoopWatch` ticks every TICK seconds and keeps each tick that came
more than NOTABLE late; `Context.expect(..., timing=True)` asks it how long the loop was held during
the case, and turns a timing failure into inconclusive when the hold was long enough to explain it:
where the check says by how much it missed, when the holds add up to that much (D-RSP-26,
D-RCTP-33: a hold delays what the harness reads by its length at most).
"""

from __future__ import annotations

import asyncio
from collections import deque

#: Seconds between ticks.
TICK = 0.005
#: A tick this much later than due is kept (seconds).
NOTABLE = 0.002
#: Holds kept at most (the oldest are forgotten first).
_KEPT = 4096


class LoopWatch:
    """Ticks on the running loop from `start` to `stop`; `held(since)` is the longest hold
    since a loop time."""

    def __init__(self) -> None:
        self._loop = asyncio.get_running_loop()
        self._due = 0.0
        self._handle: asyncio.TimerHandle | None = None
        #: (loop time the late tick ran, seconds it was late)
        self._holds: deque[tuple[float, float]] = deque(maxlen=_KEPT)

    def start(self) -> None:
        self._due = self._loop.time() + TICK
        self._handle = self._loop.call_at(self._due, self._tick)

    def _tick(self) -> None:
        now = self._loop.time()
        if now - self._due > NOTABLE:
            self._holds.append((now, now - self._due))
        self._due = now + TICK
        self._handle = self._loop.call_at(self._due, self._tick)

    def held(self, since: float) -> float:
        """The longest the loop was held (seconds) in a hold that ended after `since`."""
        return max((lag for at, lag in self._holds if at >= since), default=0.0)

    def total(self, since: float) -> float:
        """How long the loop was held (seconds) in all the holds that ended after `since`
        together: the most that they can have moved what was read off the harness's clock."""
        return sum(lag for at, lag in self._holds if at >= since)

    def stop(self) -> None:
        if self._handle is not None:
            self._handle.cancel()
            self._handle = None
