"""The adapters' timers on a real loop: a lazy deadline, and many deadlines a millisecond."""

from __future__ import annotations

import asyncio

from support.servers import run

from rcmlconf.reference.timers import BeatClock, LoopTimer


@run
async def test_a_deadline_moved_later_fires_once_at_the_later_time() -> None:
    loop = asyncio.get_running_loop()
    fired: list[float] = []
    timer = LoopTimer(loop, lambda: fired.append(loop.time()))
    start = loop.time()
    for step in range(1, 50):  # a session timeout moved on by every request
        timer.set(start + 0.01 * step / 10)
    last = start + 0.049
    await asyncio.sleep(0.1)
    assert len(fired) == 1
    assert fired[0] >= last
    timer.set(start)  # a deadline already past fires at once; None cancels
    timer.set(None)
    await asyncio.sleep(0.02)
    assert len(fired) == 1


@run
async def test_an_earlier_deadline_is_not_kept_waiting() -> None:
    loop = asyncio.get_running_loop()
    fired: list[str] = []
    late = LoopTimer(loop, lambda: fired.append("late"))
    early = LoopTimer(loop, lambda: fired.append("early"))
    late.set(loop.time() + 10)
    late.set(loop.time() + 0.01)  # moved earlier: a new handle
    early.set(loop.time() + 0.005)
    await asyncio.sleep(0.05)
    assert fired == ["early", "late"]


@run
async def test_items_due_in_one_millisecond_are_called_back_together() -> None:
    loop = asyncio.get_running_loop()
    calls: list[list[str]] = []
    clock: BeatClock[str] = BeatClock(loop, calls.append)
    base = (int(loop.time() * 1000) + 20) / 1000  # the start of a millisecond 20 ms away
    clock.set("a", base + 0.0001)
    clock.set("b", base + 0.0009)
    clock.set("c", base + 0.0015)  # the next millisecond
    clock.set("d", base + 0.0002)
    clock.set("d", None)  # taken back
    clock.set("e", base + 0.0003)
    clock.set("e", base + 0.0023)  # moved on
    await asyncio.sleep(0.05)
    assert calls == [["a", "b"], ["c"], ["e"]]


@run
async def test_a_late_clock_calls_back_at_the_end_of_the_millisecond_never_early() -> None:
    loop = asyncio.get_running_loop()
    calls: list[tuple[list[str], float]] = []
    clock: BeatClock[str] = BeatClock(
        loop, lambda items: calls.append((items, loop.time())), late=True
    )
    base = (int(loop.time() * 1000) + 20) / 1000
    clock.set("a", base + 0.0001)
    clock.set("b", base + 0.0009)
    clock.set("c", base + 0.0015)  # the next millisecond
    await asyncio.sleep(0.05)
    assert [items for items, _ in calls] == [["a", "b"], ["c"]]
    assert calls[0][1] >= base + 0.0009  # never early
    assert calls[1][1] >= base + 0.0015
