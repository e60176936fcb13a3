"""The reference server's loop, turn by turn, under bench/hostile_load.py (`--turns`).

    python bench/hostile_turns.py OUT serve ROBOT.rcml ...   # `rcmlconf serve ...`, profiled
    python bench/hostile_turns.py OUT --gc 700,10,100 serve ...  # and other collector settings
    python bench/hostile_turns.py OUT --budget 0.002 serve ...  # and another turn budget

runs `rcmlconf` in this process with its asyncio loop instrumented, and writes at exit, to OUT
(binary, `TURN` records) and OUT.json (the long turns and the collector's pauses), what each turn
of the loop took: its wall time without the wait in select(), the CPU time of the loop's thread
meanwhile (the rest of the wall time it was ready but did not run: another process had the CPU),
and the collector's time within it. A turn longer than `LONG` keeps what its callbacks took, by
kind. A select() that returned with nothing to do later than its timeout keeps how late: a
wake-up the machine delayed, not the server. `summarise` reads them back for a window of
time: what the bench's rows print beside the figures the clients saw.

The instrument costs about a microsecond a callback, so a profiled run is not the row's figures'
run: it shows what the server's turns are made of, and whether a late answer was the server
working or waiting for a CPU.
"""

from __future__ import annotations

import asyncio
import gc
import json
import selectors
import sys
import time
from array import array
from collections import defaultdict
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NamedTuple

#: A turn this long (seconds of wall time) keeps its callbacks' times by kind.
LONG = 0.005
#: A select() this late (seconds) past its timeout is kept.
LATE = 0.002
#: The legitimate clients' address, whose READs `trace_reads` follows.
TRACED = "127.0.0.1"
#: Fields a turn: its start (monotonic s), wall, CPU and collector time (s), callbacks run.
TURN = 5


class _Profile:
    def __init__(self) -> None:
        self.turns = array("d")
        self.long: list[dict[str, Any]] = []
        #: The collector's passes: when, generation, wall and CPU seconds, objects collected.
        self.pauses: list[tuple[float, int, float, float, int]] = []
        self.late: list[tuple[float, float]] = []
        self.selected = 0.0
        self.collecting = 0.0
        self._gc_started = (0.0, 0.0)
        self.callbacks: list[tuple[Any, float]] = []
        #: Seconds of callbacks by kind, a second of monotonic time at a time.
        self.spent: dict[int, defaultdict[str, float]] = {}
        self.names: dict[tuple[Any, Any, Any], str] = {}
        #: When the turn's select() returned (monotonic), and the traced READs (`trace_reads`):
        #: those received and not yet done by connection, and those done.
        self.woke = 0.0
        self.pending: dict[int, tuple[float, float, float]] = {}
        self.reads: list[tuple[float, ...]] = []

    def on_gc(self, phase: str, info: dict[str, int]) -> None:
        now = (time.perf_counter(), time.thread_time())
        if phase == "start":
            self._gc_started = now
            return
        took, used = now[0] - self._gc_started[0], now[1] - self._gc_started[1]
        self.collecting += took
        self.pauses.append((time.monotonic(), info["generation"], took, used, info["collected"]))

    def tally(self, at: float) -> None:
        """The turn's callbacks, by kind, into its second."""
        spent = self.spent.get(int(at))
        if spent is None:
            spent = self.spent[int(at)] = defaultdict(float)
        for callback, took in self.callbacks:
            owner = getattr(callback, "__self__", None)
            # Names, never the objects: a kind must not keep a callback's owner alive.
            kind: tuple[Any, Any, Any] = (
                getattr(callback, "__qualname__", None),
                type(owner),
                type(getattr(owner, "_protocol", None)),
            )
            if isinstance(owner, asyncio.Task):
                kind = (getattr(owner.get_coro(), "__qualname__", None), asyncio.Task, None)
            if kind not in self.names:
                self.names[kind] = _name(callback)
            spent[self.names[kind]] += took


def _most(spent: dict[str, float], count: int) -> list[tuple[str, float]]:
    return sorted(spent.items(), key=lambda item: -item[1])[:count]


def _name(callback: Any) -> str:
    """What a callback is, by kind: a transport's readiness names its protocol, a task its
    coroutine."""
    owner = getattr(callback, "__self__", None)
    name = getattr(callback, "__qualname__", None) or type(callback).__name__
    protocol = getattr(owner, "_protocol", None)
    if protocol is not None:
        return f"{name}[{type(protocol).__name__}]"
    if isinstance(owner, asyncio.Task):
        return f"task {getattr(owner.get_coro(), '__qualname__', '?')}"
    return str(name)


def install(out: Path) -> Callable[[], None]:
    """Instrument asyncio's loop (every loop of this process); what writes the profile."""
    profile = _Profile()
    gc.callbacks.append(profile.on_gc)
    select = selectors.DefaultSelector.select
    run_once = asyncio.base_events.BaseEventLoop._run_once  # type: ignore[attr-defined]
    run_handle = asyncio.events.Handle._run
    perf, cpu = time.perf_counter, time.thread_time

    def timed_select(self: selectors.BaseSelector, timeout: float | None = None) -> Any:
        started = perf()
        found = select(self, timeout)  # type: ignore[arg-type]
        took = perf() - started
        profile.selected += took
        profile.woke = time.monotonic()
        if not found and timeout and took - timeout > LATE:
            profile.late.append((time.monotonic(), took - timeout))
        return found

    def timed_run_once(self: asyncio.AbstractEventLoop) -> None:
        profile.selected = profile.collecting = 0.0
        profile.callbacks.clear()
        at, wall, used = time.monotonic(), perf(), cpu()
        run_once(self)
        wall = perf() - wall - profile.selected
        used = cpu() - used
        profile.turns.extend((at, wall, used, profile.collecting, len(profile.callbacks)))
        profile.tally(at)
        if wall > LONG:
            kinds: defaultdict[str, float] = defaultdict(float)
            for callback, took in profile.callbacks:
                kinds[_name(callback)] += took
            top = {kind: round(took * 1e3, 2) for kind, took in _most(kinds, 6)}
            profile.long.append(
                {"at": at, "wall": wall, "cpu": used, "gc": profile.collecting, "top": top}
            )

    def timed_handle(self: asyncio.Handle) -> None:
        started = perf()
        run_handle(self)
        profile.callbacks.append((self._callback, perf() - started))  # type: ignore[attr-defined]

    trace_reads(profile)
    selectors.DefaultSelector.select = timed_select  # type: ignore[method-assign]
    asyncio.base_events.BaseEventLoop._run_once = timed_run_once  # type: ignore[attr-defined]
    asyncio.events.Handle._run = timed_handle  # type: ignore[method-assign]

    def write() -> None:
        with out.open("wb") as file:
            profile.turns.tofile(file)
        side = {
            "long": profile.long,
            "pauses": profile.pauses,
            "late": profile.late,
            "spent": profile.spent,
            "reads": profile.reads,
        }
        out.with_suffix(".json").write_text(json.dumps(side))

    return write


def trace_reads(profile: _Profile) -> None:
    """Stamp each READ of a legitimate client (TRACED) on its way through the server: when the
    turn that read it woke, when its connection got it, when its slice began (after a wait in
    `Turns`) and ended (its answer written), and the loop thread's CPU time while it waited."""
    from rcmlconf.reference.server.adapter import _Control

    received, take = _Control.data_received, _Control._take_slice

    def data_received(self: _Control, data: bytes) -> None:
        if self.peer == TRACED and data.startswith(b"READ "):
            profile.pending[id(self)] = (profile.woke, time.monotonic(), time.thread_time())
        received(self, data)

    def take_slice(self: _Control) -> None:
        started, used = time.monotonic(), time.thread_time()
        take(self)
        pending = profile.pending.pop(id(self), None)
        if pending is not None:
            woke, got, cpu = pending
            profile.reads.append((woke, got, started, time.monotonic(), used - cpu))

    _Control.data_received = data_received  # type: ignore[method-assign]
    _Control._take_slice = take_slice  # type: ignore[method-assign]


# -- reading it back ---------------------------------------------------------------------------


@dataclass
class Turns:
    """A window's turns: counts, and percentiles in ms."""

    count: int
    wall: dict[str, float]
    cpu: dict[str, float]
    #: Wall time a turn was ready but not running (wall - CPU).
    waited: dict[str, float]
    #: Callbacks run a turn (counts, not ms).
    callbacks: dict[str, float]
    #: The collector's passes by generation: count, longest wall, CPU (ms), objects collected.
    pauses: dict[int, dict[str, Any]]
    #: Seconds of callbacks by kind, the most first, a second of the window.
    spent: dict[str, float]
    #: Wake-ups later than LATE past select's timeout: count and latest (ms).
    late: tuple[int, float]
    #: The longest turns: wall, CPU, collector (ms) and their callbacks' times by kind.
    longest: list[dict[str, Any]]


def _points(values: list[float], scale: float = 1e3) -> dict[str, float]:
    """Percentiles (nearest rank) and the largest of `values`, times `scale` (s to ms)."""
    ordered = sorted(values)
    if not ordered:
        return {}

    def at(p: float) -> float:
        return round(ordered[min(len(ordered) - 1, int(p / 100 * len(ordered)))] * scale, 2)

    return {"p50": at(50), "p99": at(99), "p99.9": at(99.9), "max": at(100)}


def _ms(key: str, value: Any) -> Any:
    return round(value * 1e3, 2) if key in ("wall", "cpu", "gc") else value


def summarise(out: Path, start: float, end: float, longest: int = 5) -> Turns | None:
    """The turns that began within [start, end) (monotonic seconds); None without a profile."""
    if not out.exists():
        return None
    turns = array("d")
    turns.frombytes(out.read_bytes())
    side = json.loads(out.with_suffix(".json").read_text())
    walls, cpus, waits, callbacks = [], [], [], []
    for index in range(0, len(turns), TURN):
        at, wall, used = turns[index], turns[index + 1], turns[index + 2]
        if start <= at < end:
            walls.append(wall)
            cpus.append(used)
            waits.append(max(0.0, wall - used))
            callbacks.append(turns[index + 4])
    passes: dict[int, list[tuple[float, float, int]]] = {}
    for at, generation, took, used, collected in side["pauses"]:
        if start <= at < end:
            passes.setdefault(generation, []).append((took, used, collected))
    pauses = {
        generation: {
            "count": len(found),
            "wall max": round(max(took for took, _, _ in found) * 1e3, 2),
            "cpu": _points([used for _, used, _ in found]),
            "cpu in all": round(sum(used for _, used, _ in found) * 1e3, 1),
            "collected": sum(collected for _, _, collected in found),
        }
        for generation, found in sorted(passes.items())
    }
    spent: defaultdict[str, float] = defaultdict(float)
    seconds = [second for second in side["spent"] if start <= int(second) < end]
    for second in seconds:
        for kind, took in side["spent"][second].items():
            spent[kind] += took
    share = {k: round(v / max(1, len(seconds)), 4) for k, v in _most(spent, 8)}
    late = [took for at, took in side["late"] if start <= at < end]
    long = sorted((t for t in side["long"] if start <= t["at"] < end), key=lambda t: -t["wall"])
    shown = [
        {
            k: round(v * 1e3, 2) if k in ("wall", "cpu", "gc") else v
            for k, v in t.items()
            if k != "at"
        }
        for t in long[:longest]
    ]
    return Turns(
        count=len(walls),
        wall=_points(walls),
        cpu=_points(cpus),
        waited=_points(waits),
        callbacks=_points(callbacks, scale=1),
        pauses=pauses,
        spent=share,
        late=(len(late), round(max(late, default=0.0) * 1e3, 2)),
        longest=shown,
    )


class Traced(NamedTuple):
    """A READ through the server (monotonic seconds): the turn that read it woke, its connection
    got it, its slice began and ended; and the loop's CPU seconds between got and began."""

    woke: float
    got: float
    began: float
    ended: float
    cpu_queued: float


def traced_reads(out: Path) -> list[Traced]:
    """The READs `trace_reads` stamped, in order; none without a profile."""
    side = out.with_suffix(".json")
    if not side.exists():
        return []
    return sorted(Traced(*read) for read in json.loads(side.read_text())["reads"])


def collect(thresholds: str) -> None:
    """Make serve's collector settings (`collector.settle`) these instead: "YOUNG,MIDDLE,OLD",
    gc.set_threshold's, to measure others."""
    from rcmlconf.reference.server import collector

    young, middle, old = (int(part) for part in thresholds.split(","))

    def settle() -> None:
        gc.freeze()
        gc.set_threshold(young, middle, old)

    collector.settle = settle


def budget(seconds: float) -> None:
    """Make the server's turns (`Turns`) this budget instead of ServerLimits.turn_budget, to
    measure others."""
    from rcmlconf.reference.server.turns import Turns

    made = Turns.__init__

    def init(self: Turns, loop: asyncio.AbstractEventLoop, _budget: float, share: float) -> None:
        made(self, loop, seconds, share)

    Turns.__init__ = init  # type: ignore[method-assign]


#: The settings `main` takes before rcmlconf's arguments, and what makes each.
SETTINGS: dict[str, Callable[[str], None]] = {
    "--gc": lambda value: collect(value),
    "--budget": lambda value: budget(float(value)),
}


def main(argv: list[str]) -> None:
    if len(argv) < 2:
        sys.exit(
            "usage: hostile_turns.py OUT [--gc YOUNG,MIDDLE,OLD] [--budget SECONDS] "
            "rcmlconf-arguments..."
        )
    write = install(Path(argv.pop(0)))
    while argv[0] in SETTINGS:
        SETTINGS[argv[0]](argv[1])
        del argv[:2]
    from rcmlconf.cli import cli  # its main() ends with os._exit: no atexit

    try:
        cli.main(args=argv, prog_name="rcmlconf")
    finally:
        write()


if __name__ == "__main__":
    main(sys.argv[1:])
