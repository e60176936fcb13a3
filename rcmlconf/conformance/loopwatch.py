"""How late the harness's own event loop ran during a case.

A timing check reads arrival times off the harness's event loop. Examples: packets T apart, or
a repeat after 250 ms. The loop may be held up: by a loaded CI machine, by a pause of the garbage
collector, or, with the embedded reference, by the target's own timers. Then datagrams are read
late, and the gaps between them are the harness's, not the target's.

`LoopWatch` ticks every TICK seconds. It keeps each tick that came more than NOTABLE late.
`Context.expect(..., timing=True)` asks it how long the loop was held during the case. A timing
failure becomes inconclusive when the holds are long enough to explain it. When the check says by
how much it missed, the holds must add up to that much. (D-RSP-26, D-RCTP-33: a hold delays what
the harness reads by its length at most.)

What a target sends never excuses the target. The harness's CPU time spent on the target's
datagrams is taken off the hold it fell in. The probes' sockets report that time with `charge`,
measured by `cpu_spent`. So a target that floods the harness is not excused by the hold it
causes.

Other holds do excuse:

- Other processes that leave the harness no CPU hold it without using its CPU time.
- Pauses of the garbage collector belong to the harness's own heap, whichever allocation set
  them off. `cpu_spent` leaves them out, so they are never taken off a hold.
"""

from __future__ import annotations

import asyncio
import gc
import time
from collections import deque
from dataclasses import dataclass
from typing import Any

#: Seconds between ticks.
TICK = 0.005
#: A tick this much later than due is kept (seconds).
NOTABLE = 0.002
#: Holds kept at most (the oldest are forgotten first).
_KEPT = 4096


@dataclass(slots=True)
class _Charged:
    """CPU seconds the process spent, since it started, on what targets sent it.

    It also holds the CPU seconds spent in the garbage collector, and when the collection under
    way began.
    """

    seconds: float = 0.0
    collecting: float = 0.0
    began: float = 0.0


_CHARGED = _Charged()


def _collected(phase: str, _: dict[str, Any]) -> None:
    now = time.thread_time()
    if phase == "start":
        _CHARGED.began = now
    else:
        _CHARGED.collecting += now - _CHARGED.began


gc.callbacks.append(_collected)


def cpu_spent() -> float:
    """CPU seconds this thread has spent so far, leaving out the garbage collector's."""
    return time.thread_time() - _CHARGED.collecting


def charge(seconds: float) -> None:
    """Record that the process spent `seconds` of CPU time on what a target sent (a datagram)."""
    _CHARGED.seconds += seconds


class LoopWatch:
    """Ticks on the running loop from `start` to `stop`, and keeps the late ticks as holds.

    `held(since)` is the longest hold since a loop time. `total(since)` is their sum.
    """

    def __init__(self) -> None:
        self._loop = asyncio.get_running_loop()
        self._due = 0.0
        #: `_CHARGED.seconds` at the last tick.
        self._charged = 0.0
        self._handle: asyncio.TimerHandle | None = None
        #: Each late tick: (the loop time it ran, the seconds it was late).
        self._holds: deque[tuple[float, float]] = deque(maxlen=_KEPT)

    def start(self) -> None:
        self._due = self._loop.time() + TICK
        self._charged = _CHARGED.seconds
        self._handle = self._loop.call_at(self._due, self._tick)

    def _tick(self) -> None:
        now = self._loop.time()
        charged = _CHARGED.seconds
        # The CPU time the targets' datagrams took since the last tick is theirs, not a hold.
        late = now - self._due - (charged - self._charged)
        self._charged = charged
        if late > NOTABLE:
            self._holds.append((now, late))
        self._due = now + TICK
        self._handle = self._loop.call_at(self._due, self._tick)

    def held(self, since: float) -> float:
        """The longest the loop was held (seconds) in a hold that ended after `since`."""
        return max((lag for at, lag in self._holds if at >= since), default=0.0)

    def total(self, since: float) -> float:
        """The sum of the holds that ended after `since`, in seconds.

        It is the most that the holds can have delayed what was read off the harness's clock.
        """
        return sum(lag for at, lag in self._holds if at >= since)

    def stop(self) -> None:
        if self._handle is not None:
            self._handle.cancel()
            self._handle = None
