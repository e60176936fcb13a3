"""How late the harness's own event loop ran during a case.

A timing check (packets T apart, a repeat after 250 ms) reads arrival times off the harness's
event loop. When that loop is held up (a loaded CI machine, a collection pause; with the embedded
reference, the target's timers too), datagrams are read late and the gaps between them are the
harness's, not the target's. `LoopWatch` ticks every TICK seconds and keeps each tick that came
more than NOTABLE late; `Context.expect(..., timing=True)` asks it how long the loop was held during
the case, and turns a timing failure into inconclusive when the hold was long enough to explain it:
where the check says by how much it missed, when the holds add up to that much (D-RSP-26,
D-RCTP-33: a hold delays what the harness reads by its length at most).

What the targets under test send never excuses them: the CPU time the harness spends handling
their datagrams (`charge`, by the probes' sockets, `cpu_spent`) is taken off the hold it fell in.
A target that floods the harness holds its loop itself; a machine that gives the harness no CPU
(other processes) holds it without that time, and still excuses; so does the garbage collector,
whose pauses are the harness's own heap's, whichever allocation set them off.
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
    """CPU seconds the process spent handling what targets sent it, since it started; and in
    the garbage collector, and when the collection under way began."""

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
    """CPU seconds this thread spent so far, but in the garbage collector."""
    return time.thread_time() - _CHARGED.collecting


def charge(seconds: float) -> None:
    """The process spent `seconds` of CPU time handling what a target sent it (a datagram)."""
    _CHARGED.seconds += seconds


class LoopWatch:
    """Ticks on the running loop from `start` to `stop`; `held(since)` is the longest hold
    since a loop time."""

    def __init__(self) -> None:
        self._loop = asyncio.get_running_loop()
        self._due = 0.0
        #: `_CHARGED` at the last tick.
        self._charged = 0.0
        self._handle: asyncio.TimerHandle | None = None
        #: (loop time the late tick ran, seconds it was late)
        self._holds: deque[tuple[float, float]] = deque(maxlen=_KEPT)

    def start(self) -> None:
        self._due = self._loop.time() + TICK
        self._charged = _CHARGED.seconds
        self._handle = self._loop.call_at(self._due, self._tick)

    def _tick(self) -> None:
        now = self._loop.time()
        charged = _CHARGED.seconds
        # Of how late this tick came, what the targets' datagrams took since the last is theirs.
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
        """How long the loop was held (seconds) in all the holds that ended after `since`
        together: the most that they can have moved what was read off the harness's clock."""
        return sum(lag for at, lag in self._holds if at >= since)

    def stop(self) -> None:
        if self._handle is not None:
            self._handle.cancel()
            self._handle = None
