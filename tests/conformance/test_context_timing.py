"""A timing check read off the harness's clock while its loop was held (D-RSP-26, D-RCTP-33):
inconclusive when the holds can explain the miss, a fail when the miss is longer than the holds
add up to, or when they were the harness's work on what the target sent it. The holds are real:
the loop is blocked, and `LoopWatch` sees it late."""

from __future__ import annotations

import asyncio
import socket
import time

import pytest

from rcmlconf.conformance.context import LATE, Context, outside_bounds
from rcmlconf.conformance.loopwatch import LoopWatch
from rcmlconf.conformance.probes.inbound import Inbound
from rcmlconf.conformance.registry import all_cases
from rcmlconf.conformance.targets import Target
from rcmlconf.conformance.transcript import Address
from rcmlconf.conformance.verdicts import Failed, Inconclusive

#: Each hold blocks the loop this long (seconds): well over LATE.
HOLD = 0.1
assert HOLD > 2 * LATE


async def _held_context(holds: int, hold: float = HOLD) -> Context:
    """A context whose case saw `holds` holds of `hold` each."""
    ctx = Context(all_cases()["rctp/client/stream-pace"], Target())
    ctx.loop_watch = LoopWatch()
    ctx.loop_watch.start()
    for _ in range(holds):
        await asyncio.sleep(0.02)
        time.sleep(hold)  # the loop is held: its next tick runs late
    await asyncio.sleep(0.02)
    return ctx


def _check(
    holds: int, by: float | None, timing: bool = True, hold: float = HOLD
) -> type[Exception]:
    async def main() -> type[Exception]:
        ctx = await _held_context(holds, hold)
        try:
            ctx.expect(False, "no DATA", "1 DATA", "R-RCTP-44", timing=timing, by=by)
        except (Failed, Inconclusive) as verdict:
            return type(verdict)
        finally:
            assert ctx.loop_watch is not None
            ctx.loop_watch.stop()
        raise AssertionError("a failed check passed")

    return asyncio.run(main())


def test_a_miss_the_holds_explain_is_inconclusive() -> None:
    assert _check(holds=1, by=HOLD / 2) is Inconclusive
    assert _check(holds=1, by=None) is Inconclusive  # a check that cannot say by how much


def test_holds_add_up() -> None:
    assert _check(holds=3, by=2.5 * HOLD) is Inconclusive


def test_many_short_holds_add_up() -> None:
    """A process short of CPU is held many times a little, none of them LATE: where the check
    says by how much it missed, what they add up to is what excuses it."""
    short = LATE / 2
    assert _check(holds=12, by=4 * short, hold=short) is Inconclusive
    assert _check(holds=12, by=40 * short, hold=short) is Failed
    assert _check(holds=12, by=None, hold=short) is Failed  # no measure: only a LATE hold


def test_a_miss_longer_than_the_holds_add_up_to_fails() -> None:
    assert _check(holds=1, by=5 * HOLD) is Failed
    assert _check(holds=2, by=5 * HOLD) is Failed


def _held_by_a_datagram(on_cpu: bool) -> type[Exception]:
    """A check after a hold the loop spent in a probe's socket on a target's datagram: HOLD of
    the CPU (the harness handling a flood: by as much as the hold was longer, plus 50 ms), or
    asleep HOLD (a machine that gave the CPU to other processes meanwhile: by HOLD / 2)."""
    took: list[float] = []

    def arrived(data: bytes, source: Address, at: float) -> None:
        started = time.perf_counter()
        if on_cpu:
            until = time.thread_time() + HOLD
            while time.thread_time() < until:
                pass
        else:
            time.sleep(HOLD)
        took.append(time.perf_counter() - started)

    async def main() -> type[Exception]:
        ctx = Context(all_cases()["rctp/client/stream-pace"], Target())
        loop = asyncio.get_running_loop()
        transport, _ = await loop.create_datagram_endpoint(
            lambda: Inbound(arrived), local_addr=("127.0.0.1", 0)
        )
        watch = ctx.loop_watch = LoopWatch()
        watch.start()
        try:
            await asyncio.sleep(0.02)
            with socket.socket(type=socket.SOCK_DGRAM) as target:
                target.sendto(b"flood", transport.get_extra_info("sockname"))
            while not took:
                await asyncio.sleep(0.01)
            await asyncio.sleep(0.02)
            by = took[0] - HOLD + 0.05 if on_cpu else HOLD / 2
            ctx.expect(False, "no DATA", "1 DATA", "R-RCTP-44", timing=True, by=by)
        except (Failed, Inconclusive) as verdict:
            return type(verdict)
        finally:
            watch.stop()
            transport.close()
        raise AssertionError("a failed check passed")

    return asyncio.run(main())


def test_a_hold_spent_on_the_targets_datagrams_excuses_nothing() -> None:
    """What the target sends never excuses it: the harness on the CPU handling its datagrams is
    the target's load; the harness kept off the CPU as long is a loaded machine's, and excuses."""
    assert _held_by_a_datagram(on_cpu=True) is Failed
    assert _held_by_a_datagram(on_cpu=False) is Inconclusive


def test_no_hold_or_no_timing_check_fails() -> None:
    assert _check(holds=0, by=None) is Failed
    assert _check(holds=1, by=None, timing=False) is Failed


@pytest.mark.parametrize(
    ("value", "low", "high", "far"),
    [(5, 1, 10, 0.0), (0, 1, 10, 1.0), (12, 1, 10, 2.0), (1, 1, 1, 0.0)],
)
def test_outside_bounds(value: float, low: float, high: float, far: float) -> None:
    assert outside_bounds(value, low, high) == far
