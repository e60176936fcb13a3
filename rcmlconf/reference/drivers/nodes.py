"""What a simulated driver needs to know about a data node: its first value, how to fit a number
to it, and whether a model's node is what a specialised driver expects.

Everything a driver computes (a wheel speed, a sensor reading, a wandering value) goes through
`fit` before the server sees it, so a value is always one the node can hold: inside `min`/`max`
(D-RCML-12) and the integer type's range, and exactly representable in float32 (D-RCML-9), so
an encode/decode round trip gives it back unchanged.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Iterable
from dataclasses import dataclass

from rcmlconf.rcml.model import DataNode, Permission, RcmlDocument
from rcmlconf.values import Kind, Scalar, Value, ValueType

_FLOAT32 = struct.Struct(">f")


def bounds(node: DataNode) -> tuple[float, float]:
    """The values a number of `node` may take: `min`/`max`, within the integer type's range."""
    base = node.type.base
    if base.kind is Kind.INTEGER:
        low: float = base.low if node.minimum is None else max(base.low, node.minimum)
        high: float = base.high if node.maximum is None else min(base.high, node.maximum)
        return low, high
    low = -math.inf if node.minimum is None else node.minimum
    high = math.inf if node.maximum is None else node.maximum
    return low, high


def fit(node: DataNode, number: float) -> int | float:
    """`number` as a value of `node`: clamped into its bounds, rounded to its type.

    Rounding to float32 after clamping cannot leave the range: `min` and `max` of a float32 node
    are float32 values themselves (the loader rounds them), and rounding is monotonic.
    """
    low, high = bounds(node)
    base = node.type.base
    if base.kind is Kind.INTEGER:
        # Clamp the rounded int, not the float: as a float, the top of int64 is 2**63, one past it.
        return int(min(max(round(number), low), high))
    clamped = float(min(max(number, low), high))
    if base.name == "float32":
        return float(_FLOAT32.unpack(_FLOAT32.pack(clamped))[0])
    return clamped


def fit_text(text: str, size: int) -> str:
    """`text` cut to at most `size` bytes of UTF-8, never in the middle of a character."""
    return text.encode("utf-8")[:size].decode("utf-8", "ignore")


def first_value(node: DataNode) -> Value:
    """A node's value when a simulated robot starts: zero (clamped), False, its name, no bytes."""
    kind = node.type.base.kind
    item: Scalar
    if kind is Kind.BOOL:
        item = False
    elif kind is Kind.INTEGER or kind is Kind.FLOAT:
        item = fit(node, 0)
    elif kind is Kind.STRING:
        item = fit_text(node.name, node.type.size)
    else:
        item = b""
    return (item,) * node.type.count if node.type.is_array else item


def first_values(nodes: Iterable[DataNode]) -> dict[str, Value]:
    """Every node's first value, by path. Nodes alike in type and range share one: a robot of
    100,000 nodes has a handful of kinds, and hashing is cheaper than fitting."""
    values: dict[str, Value] = {}
    shared: dict[tuple[ValueType, float | None, float | None], Value] = {}
    for node in nodes:
        if node.type.base.kind is Kind.STRING:  # the node's name
            values[node.path] = first_value(node)
            continue
        key = (node.type, node.minimum, node.maximum)
        value = shared.get(key)
        if value is None:
            value = shared[key] = first_value(node)
        values[node.path] = value
    return values


@dataclass(frozen=True, slots=True)
class Need:
    """A data node a specialised driver works with: where, of what kind, with which rights.

    Any size of integer or float will do: the driver fits what it computes to the node.
    """

    path: str
    kind: Kind
    permission: Permission = Permission.READ
    count: int = 1

    def problem(self, model: RcmlDocument) -> str | None:
        """Why `model` does not have this node, or None."""
        node = model.node(self.path)
        if not isinstance(node, DataNode):
            return f"it has no data node {self.path}"
        if node.type.base.kind is not self.kind or node.type.count != self.count:
            wanted = self.kind.value + (f"[{self.count}]" if self.count > 1 else "")
            return f"{self.path} is {node.type}, not {wanted}"
        if self.permission not in node.permission:
            return (
                f"{self.path} has permission {node.permission.to_text()}, "
                f"not {self.permission.to_text()}"
            )
        return None


def unmet(model: RcmlDocument, needs: tuple[Need, ...]) -> str | None:
    """The first of `needs` that `model` does not meet, described; None when it meets them all."""
    return next((p for need in needs if (p := need.problem(model)) is not None), None)


def number(value: Value) -> float:
    """A written value of a numeric scalar node, which the server has checked it is."""
    assert isinstance(value, int | float), value
    return value
