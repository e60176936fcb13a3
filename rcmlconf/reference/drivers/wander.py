"""Read-only values that change by themselves, so that streams and events carry real changes.

Each motion is a closed form of the time since the start: a number bounces between the ends of
its band at a steady speed, a bool flips at a steady period. A jump of hours costs what a jump of
milliseconds does, and the value a node is refreshed to depends only on the seed and the time,
not on the times of earlier calls.

A robot may have 100,000 wandering nodes, and arrays of 65,535 items: refreshing everything on
each advance would cost seconds. `Wander.refresh` instead computes at most `ITEMS_PER_ADVANCE`
items per call, going round the nodes (and through a long array a window at a time) from where
the last call stopped. A small robot refreshes every node on every advance; a robot of 100,000
scalars refreshes each about every 400 advances (8 s at 50 advances a second).
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Callable, Iterable, Mapping
from random import Random

from rcmlconf.rcml.model import DataNode, Permission
from rcmlconf.reference.drivers.nodes import bounds, fit
from rcmlconf.values import Kind, Scalar, Value

#: Items (array elements or scalars) computed per refresh: a few hundred microseconds of Python.
ITEMS_PER_ADVANCE = 256
#: How far a number with a wide (or no) range strays from its first value.
REACH = 1000.0
#: Seconds a number takes to cross its band, and a bool's time between flips, drawn per node.
CROSSING = (10.0, 60.0)
FLIP = (2.0, 8.0)

_MOVING = (Kind.BOOL, Kind.INTEGER, Kind.FLOAT)
#: Sets a node's value (the driver's own bookkeeping of what changed).
Setter = Callable[[str, Value], None]


class _Motion(ABC):
    """One wandering node. Item `i` of an array runs `1 + i / count` times as fast as item 0, so
    an array's items drift apart instead of moving in lockstep."""

    __slots__ = ("count", "node")

    def __init__(self, node: DataNode) -> None:
        self.node = node
        self.count = node.type.count

    @abstractmethod
    def item(self, index: int, elapsed: float) -> Scalar:
        """Item `index`'s value `elapsed` seconds after the start."""


class _Drift(_Motion):
    """A number bouncing between the ends of its band (its range, at most `REACH` either side of
    its first value) at a steady speed, from its first value in a random direction."""

    __slots__ = ("low", "offset", "speed", "width")

    def __init__(self, node: DataNode, first: float, low: float, high: float, rng: Random) -> None:
        super().__init__(node)
        self.low = low
        self.width = high - low
        self.offset = first - low
        direction = 1 if rng.random() < 0.5 else -1
        self.speed = direction * self.width / rng.uniform(*CROSSING)

    def item(self, index: int, elapsed: float) -> Scalar:
        travel = self.speed * (1 + index / self.count) * elapsed
        folded = (self.offset + travel) % (2 * self.width)
        return fit(self.node, self.low + min(folded, 2 * self.width - folded))


class _Blink(_Motion):
    """A bool that flips every `period` seconds, first after a random part of a period."""

    __slots__ = ("first", "period", "phase")

    def __init__(self, node: DataNode, first: bool, rng: Random) -> None:
        super().__init__(node)
        self.first = first
        self.period = rng.uniform(*FLIP)
        self.phase = rng.random()

    def item(self, index: int, elapsed: float) -> Scalar:
        flips = math.floor(elapsed / (self.period * (1 + index / self.count)) + self.phase)
        return self.first != (flips % 2 == 1)


def _motion(node: DataNode, first: Value, rng: Random) -> _Motion | None:
    """How a read-only number or bool wanders, or None when its band leaves it nowhere to go."""
    start = first[0] if isinstance(first, tuple) else first
    if node.type.base.kind is Kind.BOOL:
        return _Blink(node, bool(start), rng)
    assert isinstance(start, int | float)
    low, high = bounds(node)
    low, high = max(low, start - REACH), min(high, start + REACH)
    return _Drift(node, start, low, high, rng) if high > low else None


class Wander:
    """The wandering nodes of a robot and where the round of refreshes has got to.

    A node wanders when a client can read it but not write it (a written node holds what was
    written; nobody would see an unreadable one) and it is a number or a bool: text stays put.
    """

    def __init__(self, nodes: Iterable[tuple[DataNode, Value]], seed: int, start: float) -> None:
        """`nodes`: data nodes with their first values, in a fixed order."""
        self._rng = Random(seed)
        self._start = start
        self._nodes = [
            (node, first)
            for node, first in nodes
            if node.permission is Permission.READ and node.type.base.kind in _MOVING
        ]
        #: Their motions (None: it stays put), each made when the round first reaches it: the
        #: random draws follow the nodes' order whatever the times of the calls, and starting a
        #: robot of 100,000 nodes costs no 100,000 draws.
        self._motions: list[_Motion | None] = []
        #: The next node to refresh, and the first of its items.
        self._next = 0
        self._item = 0

    def refresh(self, values: Mapping[str, Value], now: float, set_value: Setter) -> None:
        """Compute the next `ITEMS_PER_ADVANCE` items at `now` and set their nodes' values; a
        node that stays put counts as one item."""
        elapsed = now - self._start
        budget = ITEMS_PER_ADVANCE
        for _ in range(len(self._nodes)):  # each node at most once a call
            if self._next == len(self._motions):
                self._motions.append(_motion(*self._nodes[self._next], self._rng))
            motion = self._motions[self._next]
            count = 1 if motion is None else motion.count
            first, stop = self._item, min(count, self._item + budget)
            if motion is not None:
                items = tuple(motion.item(index, elapsed) for index in range(first, stop))
                path = motion.node.path
                if count == 1:
                    set_value(path, items[0])
                else:
                    old = values[path]
                    assert isinstance(old, tuple)
                    set_value(path, old[:first] + items + old[stop:])
            budget -= stop - first
            if stop < count:
                self._item = stop
            else:
                self._next, self._item = (self._next + 1) % len(self._nodes), 0
            if budget == 0:
                break
