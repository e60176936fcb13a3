"""A sans-IO core's `get_timer()` as one asyncio timer handle, for the adapters."""

from __future__ import annotations

import asyncio
from collections.abc import Callable


class LoopTimer:
    """One loop timer, moved only when the wanted time changes (most calls change nothing)."""

    __slots__ = ("_at", "_callback", "_handle", "_loop")

    def __init__(self, loop: asyncio.AbstractEventLoop, callback: Callable[[], None]) -> None:
        self._loop = loop
        self._callback = callback
        self._handle: asyncio.TimerHandle | None = None
        self._at: float | None = None

    def set(self, at: float | None) -> None:
        """Call back at loop time `at`; None: not at all."""
        if at == self._at:
            return
        if self._handle is not None:
            self._handle.cancel()
            self._handle = None
        self._at = at
        if at is not None:
            self._handle = self._loop.call_at(at, self._fire)

    def _fire(self) -> None:
        self._handle = self._at = None
        self._callback()
