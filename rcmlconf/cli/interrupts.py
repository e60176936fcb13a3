"""Ctrl-C and SIGTERM as something a running command awaits, not an exception.

A command that runs until interrupted (`serve`, `client stream`, ...) has work to finish after
the signal: BYE to its peers, STOP, a summary. KeyboardInterrupt would arrive wherever the loop
happens to be and leave that undone, so while the command runs the signals only set a flag and
wake whoever awaits it.
"""

from __future__ import annotations

import asyncio
import signal
from collections.abc import Awaitable
from typing import TypeVar

T = TypeVar("T")

_SIGNALS = (signal.SIGINT, signal.SIGTERM)


class Interrupts:
    """Use as `with Interrupts() as interrupts:` inside the running loop (Unix only)."""

    def __init__(self) -> None:
        #: Signals caught so far: the first asks to finish, a second not to wait any longer.
        self.count = 0
        self._caught = asyncio.Event()

    def __enter__(self) -> Interrupts:
        loop = asyncio.get_running_loop()
        for number in _SIGNALS:
            loop.add_signal_handler(number, self._catch)
        return self

    def __exit__(self, *exc: object) -> None:
        loop = asyncio.get_running_loop()
        for number in _SIGNALS:
            loop.remove_signal_handler(number)  # SIGINT raises KeyboardInterrupt again

    def _catch(self) -> None:
        self.count += 1
        self._caught.set()

    async def wait(self, count: int = 1) -> None:
        """Until `count` signals in all have been caught."""
        while self.count < count:
            self._caught.clear()
            await self._caught.wait()

    async def race(self, work: Awaitable[T], count: int = 1) -> T | None:
        """`work`'s result, or None when the `count`th signal comes first (`work` is cancelled).

        What `work` finished before the signal is never lost: its result wins a tie.
        """
        task = asyncio.ensure_future(work)
        signalled = asyncio.ensure_future(self.wait(count))
        try:
            await asyncio.wait((task, signalled), return_when=asyncio.FIRST_COMPLETED)
        finally:
            for future in (task, signalled):
                if not future.done():
                    future.cancel()
        return task.result() if task.done() and not task.cancelled() else None
