"""What the scale benches share (how many periodic streams one core holds): the CPUs, kernel
receive stamps, CPU use from /proc, jitter percentiles, the steps of N, a row's verdict against
its anchor and the best of several tries.

A bench's row is any object with `passed`, `lost`, `silent`, `rate`, `tries` and
`percentile(p)` (jitter in ms, nearest rank): `Scored`.
"""

from __future__ import annotations

import contextlib
import os
import socket
import struct
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol, TypeVar

from children import cpu_seconds

#: Linux's values where the socket module does not name them.
SO_TIMESTAMPNS = getattr(socket, "SO_TIMESTAMPNS", 35)
#: The struct timespec of an SO_TIMESTAMPNS control message.
TIMESPEC = struct.Struct("@qq")
#: A row passes only when this share of the packets due came.
MIN_RATE = 0.99


def stamp_ns(ancillary: bytes) -> int:
    """The kernel's receive time (CLOCK_REALTIME, ns) of an SO_TIMESTAMPNS control message."""
    seconds, nanoseconds = TIMESPEC.unpack(ancillary)
    return int(seconds) * 1_000_000_000 + int(nanoseconds)


def split_cpus() -> tuple[int | None, int | None]:
    """Pin this process (the measurer) to the last CPU; (the first CPU, for the measured
    process; the last), or (None, None) on a single CPU, where both share it."""
    cpus = sorted(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else []
    if len(cpus) < 2:
        return None, None
    os.sched_setaffinity(0, {cpus[-1]})
    return cpus[0], cpus[-1]


def load_average() -> str:
    path = Path("/proc/loadavg")
    return path.read_text().split()[0] if path.exists() else "?"


@dataclass
class Usage:
    """CPU use over the window, as fractions of one CPU: the measured process's (`sender`), the
    measurer's (`generator`: this process); on the measured process's CPU, the time the
    hypervisor took (steal) and what other processes used."""

    sender: float = 0.0
    generator: float = 0.0
    steal: float = 0.0
    other: float = 0.0


class UsageProbe:
    """CPU use from now until `usage()`: of process `pid`, and of CPU `cpu` (from /proc)."""

    def __init__(self, pid: int | None, cpu: int | None) -> None:
        self.pid, self.cpu = pid, cpu
        self.start = self._read()

    def _read(self) -> tuple[float, float, float, float, float]:
        busy = steal = 0.0
        with contextlib.suppress(OSError, ValueError, IndexError):
            for line in Path("/proc/stat").read_text().splitlines():
                name, *fields = line.split()
                if name == f"cpu{self.cpu}":
                    ticks = [int(f) / os.sysconf("SC_CLK_TCK") for f in fields]
                    busy = ticks[0] + ticks[1] + ticks[2] + ticks[5] + ticks[6]
                    steal = ticks[7]
        sender = cpu_seconds(self.pid) if self.pid is not None else 0.0
        return time.monotonic(), sender, time.process_time(), busy, steal

    def usage(self) -> Usage:
        end = self._read()
        wall, sender, generator, busy, steal = (b - a for a, b in zip(self.start, end, strict=True))
        return Usage(sender / wall, generator / wall, steal / wall, max(0.0, busy - sender) / wall)


def percentile(jitter: Sequence[int], p: float) -> float:
    """Jitter in ms at percentile p (nearest rank) of sorted nanoseconds; inf when empty."""
    if not jitter:
        return float("inf")
    index = min(len(jitter) - 1, max(0, round(p / 100 * len(jitter)) - 1))
    return jitter[index] / 1e6


def steps(
    max_n: int, quick: bool, full: Sequence[int], quick_steps: Sequence[int] = (50, 200)
) -> Iterator[int]:
    """The Ns of a run: `quick_steps`, or `full` and then max_n, up to max_n."""
    if quick:
        yield from (n for n in quick_steps if n <= max_n)
        return
    yield from (n for n in full if n <= max_n)
    if max_n not in full and max_n > 0:
        yield max_n


class Scored(Protocol):
    tries: int

    @property
    def passed(self) -> bool: ...

    @property
    def lost(self) -> int: ...

    @property
    def silent(self) -> int: ...

    @property
    def rate(self) -> float: ...

    def percentile(self, p: float) -> float: ...


R = TypeVar("R", bound=Scored)


def verdict(row: Scored, anchor: Scored | None = None, noisy: float = 1.5) -> str:
    """pass; FAIL; or `noisy`: failed by jitter alone where the anchor failed too, with a p99
    at most `noisy` times the anchor's (the machine's doing, as far as this run can tell)."""
    if row.passed:
        return "pass"
    if row.lost or row.silent or row.rate < MIN_RATE or anchor is None or anchor.passed:
        return "FAIL"
    return "noisy" if row.percentile(99) <= noisy * anchor.percentile(99) else "FAIL"


def best_of(run: Callable[[], R], tries: int) -> R:
    """Up to `tries` rows until one passes; the best (the machine's noise only adds jitter)."""
    rows = []
    for _ in range(max(1, tries)):
        row = run()
        rows.append(row)
        if row.passed:
            break
    best = min(rows, key=lambda r: (not r.passed, r.percentile(99)))
    best.tries = len(rows)
    return best
