"""`sim`: a robot for any RCML model, and the base of the specialised simulated robots.

Every node starts at a value valid for its type and range (`nodes.first_value`). Nodes a client
can write hold what was last written; nodes it can only read wander (`wander`); a subclass
computes the nodes it `needs` itself, from what is written and the time that passes.

Each change is reported once, by the call it belongs to. `command` returns the changes its values
made, no more: the server tells every session but the writer of them (R-RCTP-54), so the writer
must still hear of everything else. It first moves the robot to its `now` (so a wheel turns at its
old speed until the moment the new one is written), and what that move changed is reported by the
next `advance`, with what moves after.
"""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType
from typing import ClassVar

from rcmlconf.rcml.model import DataNode, RcmlDocument
from rcmlconf.reference.drivers.nodes import Need, first_values, fit, fit_text, unmet
from rcmlconf.reference.drivers.wander import Wander
from rcmlconf.values import Value


class SimulatedRobot:
    """A `Driver` (see the package) for any valid model."""

    name: str = "sim"
    #: The nodes a specialised robot computes itself: a model must have them, and they never
    #: wander.
    needs: ClassVar[tuple[Need, ...]] = ()

    @classmethod
    def mismatch(cls, model: RcmlDocument) -> str | None:
        """Why this robot cannot drive `model`, or None."""
        return unmet(model, cls.needs)

    @classmethod
    def fits(cls, model: RcmlDocument) -> bool:
        return cls.mismatch(model) is None

    def start(self, model: RcmlDocument, now: float, seed: int) -> None:
        """Take the robot: first values, and the wandering nodes' motions drawn from `seed`."""
        self._model = model
        self._now = now
        nodes = list(model.data_nodes())
        self._values = first_values(nodes)
        self._view = MappingProxyType(self._values)
        #: Paths set since their last report, with their values then: a path is reported when
        #: its value differs (a bool that flipped and flipped back did not change).
        self._changed: dict[str, Value] = {}
        owned = {need.path for need in self.needs}
        self._wander = Wander(
            ((node, self._values[node.path]) for node in nodes if node.path not in owned),
            seed,
            now,
        )
        self._begin()
        self._changed.clear()  # first values are not changes

    def values(self) -> Mapping[str, Value]:
        """A live, read-only view: it shows each change as it is made."""
        return self._view

    def advance(self, now: float) -> list[str]:
        self._move(now)
        return self._flush()

    def command(self, values: Mapping[str, Value], now: float) -> list[str]:
        self._move(now)
        moved, self._changed = self._changed, {}
        self._write(values)
        written, self._changed = self._changed, moved
        # Measured against what was last reported: a value the move changed and the write changed
        # back did not change at all, and the write's report covers the move's.
        return [
            path
            for path, old in written.items()
            if not _same(moved.pop(path, old), self._values[path])
        ]

    # -- what a specialised robot overrides ----------------------------------------------------

    def _begin(self) -> None:
        """Set the first values of the nodes in `needs` and the robot's own state."""

    def _simulate(self, elapsed: float) -> None:
        """Move the robot on by `elapsed` seconds (more than zero) of physics."""

    def _write(self, values: Mapping[str, Value]) -> None:
        """Take written values, all together: here, each node holds what was written."""
        for path, value in values.items():
            self._set(path, value)

    # -- for subclasses ----------------------------------------------------------------------

    def _node(self, path: str) -> DataNode:
        node = self._model.node(path)
        assert isinstance(node, DataNode), path  # a path of `needs`, which `fits` checked
        return node

    def _set(self, path: str, value: Value) -> None:
        old = self._values[path]
        if not _same(old, value):
            self._changed.setdefault(path, old)
            self._values[path] = value

    def _set_numbers(self, path: str, *numbers: float) -> None:
        """Set a number (or, given several, an array) each fitted to the node (`nodes.fit`)."""
        node = self._node(path)
        items = tuple(fit(node, number) for number in numbers)
        assert len(items) == node.type.count, path
        self._set(path, items if node.type.is_array else items[0])

    def _set_text(self, path: str, text: str) -> None:
        self._set(path, fit_text(text, self._node(path).type.size))

    # -- the common part -----------------------------------------------------------------------

    def _move(self, now: float) -> None:
        """Move to `now` (nothing moves when no time passed)."""
        if now <= self._now:
            return
        elapsed, self._now = now - self._now, now
        self._wander.refresh(self._values, now, self._set)
        self._simulate(elapsed)

    def _flush(self) -> list[str]:
        values = self._values
        changed = [path for path, old in self._changed.items() if not _same(old, values[path])]
        self._changed.clear()
        return changed


def _same(old: Value, new: Value) -> bool:
    """Python's own test for a value in a container: the same object, or equal. A NaN a client
    writes again is a change, unless it is the very same object."""
    return old is new or old == new
