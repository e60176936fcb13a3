"""A sans-IO core's timers as asyncio timer handles, for the adapters."""

from __future__ import annotations

import asyncio
import math
from collections.abc import Callable
from typing import Generic, TypeVar

T = TypeVar("T")


class LoopTimer:
    """One loop timer for a deadline that moves often and mostly later.

    Every request moves a session's timeout on; cancelling and making a loop timer each time
    would cost a few microseconds a request and leave a cancelled handle in the loop's heap. So
    a handle that would fire earlier than the new deadline is kept: it fires, finds the deadline
    ahead, and waits again for the rest. Only an earlier deadline makes a new handle.
    """

    __slots__ = ("_at", "_callback", "_handle", "_handle_at", "_loop")

    def __init__(self, loop: asyncio.AbstractEventLoop, callback: Callable[[], None]) -> None:
        self._loop = loop
        self._callback = callback
        self._handle: asyncio.TimerHandle | None = None
        self._handle_at = 0.0
        self._at: float | None = None

    def set(self, at: float | None) -> None:
        """Call back at loop time `at`; None: not at all."""
        self._at = at
        if at is None:
            if self._handle is not None:
                self._handle.cancel()
                self._handle = None
        elif self._handle is None or at < self._handle_at:
            self._arm(at)

    def _arm(self, at: float) -> None:
        if self._handle is not None:
            self._handle.cancel()
        self._handle_at = at
        self._handle = self._loop.call_at(at, self._fire)

    def _fire(self) -> None:
        self._handle = None
        at = self._at
        if at is None:
            return
        if at > self._handle_at:  # the deadline moved on since this handle was made
            self._arm(at)
            return
        self._at = None
        self._callback()


class BeatClock(Generic[T]):
    """Many items' deadlines on one loop timer per millisecond.

    A server with hundreds of sessions streaming every 16 ms would otherwise make and fire a
    loop timer per packet, and the loop's heap of them costs more than the packets. Deadlines
    are put in the millisecond they fall in and the millisecond is called back whole, at its
    start: at most 1 ms early, which D-RCTP-20's slack for streams sent together allows
    (`endpoint.SEND_SLACK`). With `late`, at its end instead: at most 1 ms late and never early,
    for endpoints that act only once their deadline has come (RSP's beats, D-RSP-13); a periodic
    deadline keeps its place within the millisecond, so the rounding adds no jitter.
    """

    __slots__ = ("_buckets", "_callback", "_keys", "_loop", "_round")

    def __init__(
        self,
        loop: asyncio.AbstractEventLoop,
        callback: Callable[[list[T]], None],
        *,
        late: bool = False,
    ) -> None:
        self._loop = loop
        self._callback = callback
        self._round = math.ceil if late else math.floor
        #: Millisecond -> the items due in it (a dict for an ordered set).
        self._buckets: dict[int, dict[T, None]] = {}
        self._keys: dict[T, int] = {}

    def set(self, item: T, at: float | None) -> None:
        """Call back with `item` in the millisecond of loop time `at`; None: not at all."""
        key = None if at is None else self._round(at * 1000)
        old = self._keys.get(item)
        if old == key:
            return
        if old is not None:
            self._buckets.get(old, {}).pop(item, None)
        if key is None:
            del self._keys[item]
            return
        self._keys[item] = key
        bucket = self._buckets.get(key)
        if bucket is None:
            bucket = self._buckets[key] = {}
            self._loop.call_at(key / 1000, self._fire, key)
        bucket[item] = None

    def _fire(self, key: int) -> None:
        items = list(self._buckets.pop(key, {}))
        for item in items:
            del self._keys[item]
        if items:
            self._callback(items)
