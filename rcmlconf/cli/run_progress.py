"""`rcmlconf run`'s progress in a CI log: where standard error is no terminal (no live bar), a
line every EVERY_CASES results and whenever EVERY_SECONDS pass without one, so that a log shows
the run is alive and how it goes: `120/259 cases, 2 fail (35 s)`."""

from __future__ import annotations

import asyncio
import contextlib
import time
from collections import Counter
from collections.abc import AsyncIterator, Callable

from rcmlconf.cli.console import Output
from rcmlconf.conformance.verdicts import Result, Verdict

EVERY_CASES = 25
EVERY_SECONDS = 5.0


class _Log:
    def __init__(self, output: Output, total: int) -> None:
        self.output, self.total = output, total
        self.found: Counter[Verdict] = Counter()
        self.started = self.last = time.monotonic()

    def result(self, result: Result) -> None:
        self.found[result.verdict] += 1
        if self.found.total() % EVERY_CASES == 0:
            self.line()

    def line(self) -> None:
        self.last = time.monotonic()
        said = f"{self.found.total()}/{self.total} cases, {self.found[Verdict.FAIL]} fail"
        if self.found[Verdict.ERROR]:
            said += f", {self.found[Verdict.ERROR]} error"
        self.output.err.line([(f"{said} ({self.last - self.started:.0f} s)", "dim")])
        self.output.err.file.flush()

    async def beat(self) -> None:
        """A line whenever EVERY_SECONDS pass without one."""
        while True:
            await asyncio.sleep(max(self.last + EVERY_SECONDS - time.monotonic(), 0.0))
            if time.monotonic() - self.last >= EVERY_SECONDS:
                self.line()


@contextlib.asynccontextmanager
async def log_progress(output: Output, total: int) -> AsyncIterator[Callable[[Result], None]]:
    """What to call with each result: lines on a log, nothing on a terminal (the bar is there)."""
    if output.err.file.isatty():
        yield lambda _: None
        return
    log = _Log(output, total)
    beat = asyncio.create_task(log.beat())
    try:
        yield log.result
    finally:
        beat.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await beat
