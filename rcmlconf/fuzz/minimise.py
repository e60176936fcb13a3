"""Delta debugging (Zeller's ddmin): the smallest part of a finding that still fires its oracle
(D-FUZZ-6). First over the steps, then over the bytes of each step that is left.

`fires` runs a candidate against the target and says whether the same oracle fires; every call
is a real run, so the search is bounded by `tries`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import replace
from typing import TypeVar

from rcmlconf.fuzz.steps import Step, TestCase

T = TypeVar("T")
#: The most runs one minimisation makes.
TRIES = 200


class _Budget:
    def __init__(self, tries: int) -> None:
        self.left = tries

    def spend(self) -> bool:
        self.left -= 1
        return self.left >= 0


def ddmin(items: Sequence[T], fires: Callable[[list[T]], bool], budget: _Budget) -> list[T]:
    """A 1-minimal sublist of `items` for which `fires` holds, as far as `budget` goes;
    `items` itself is assumed to fire."""
    current = list(items)
    parts = 2
    while len(current) >= 2:
        size = -(-len(current) // parts)
        chunks = [current[i : i + size] for i in range(0, len(current), size)]
        reduced = False
        for index in range(len(chunks)):
            rest = [x for j, chunk in enumerate(chunks) if j != index for x in chunk]
            if not budget.spend():
                return current
            if rest and fires(rest):
                current, parts, reduced = rest, max(parts - 1, 2), True
                break
        if not reduced:
            if parts >= len(current):
                return current
            parts = min(len(current), parts * 2)
    return current


def minimise(case: TestCase, fires: Callable[[TestCase], bool], tries: int = TRIES) -> TestCase:
    """`case` with as few steps, and as few bytes in them, as still fire (D-FUZZ-6)."""
    budget = _Budget(tries)
    steps = ddmin(case.steps, lambda kept: fires(case.with_steps(tuple(kept))), budget)
    for index in range(len(steps)):
        step = steps[index]

        def with_bytes(kept: list[int], index: int = index, step: Step = step) -> bool:
            changed = replace(step, data=bytes(kept))
            trial = [*steps[:index], changed, *steps[index + 1 :]]
            return fires(case.with_steps(tuple(trial)))

        if len(step.data) <= 512:  # ddmin over a huge field costs more runs than it saves
            kept = ddmin(list(step.data), with_bytes, budget)
            steps[index] = replace(step, data=bytes(kept))
    return case.with_steps(tuple(steps))
