"""A recurring condition logged once an interval, with how often it happened meanwhile: a flood
(of refused connections, failed accepts, hostile datagrams) must not become a flood of log lines,
nor cost a line's work each time (D-RCTP-32)."""

from __future__ import annotations

import logging

#: A condition is logged once in this many seconds, however often it happens.
INTERVAL = 10.0


class Throttled:
    __slots__ = ("_count", "_interval", "_last", "_log", "_what")

    def __init__(self, log: logging.Logger, what: str, interval: float = INTERVAL) -> None:
        self._log = log
        self._what = what
        self._interval = interval
        self._last: float | None = None
        self._count = 0

    def happened(self, now: float, detail: str) -> None:
        self._count += 1
        if self._last is not None and now - self._last < self._interval:
            return
        more = f" ({self._count - 1} more since the last notice)" if self._count > 1 else ""
        self._log.warning("%s: %s%s", self._what, detail, more)
        self._last = now
        self._count = 0
