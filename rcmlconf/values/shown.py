"""Values in their text form (D-RCML-14) as a person reads them in a line of output: a value of a
node, or `name=value` for each of several. An array is its items joined by commas, as
`rcmlconf client` takes them; a string's control characters are escaped (`\\x1b`), so that a
robot's string cannot move a terminal's cursor or split a line. The command line, the
conformance reports and the analysers all show values this way."""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Protocol

from rcmlconf.values.text import format_value_text
from rcmlconf.values.types import DataType, Scalar, Value, ValueType

#: C0 and C1 controls and DEL.
_CONTROLS = {c: f"\\x{c:02x}" for c in (*range(0x20), *range(0x7F, 0xA0))}


class Typed(Protocol):
    """What holds a value: an RCML data node, an RSP field."""

    @property
    def name(self) -> str: ...

    @property
    def type(self) -> ValueType: ...


def value_text(vtype: ValueType, value: Value) -> str:
    """A value of `vtype` in its text form, an array's items joined by commas."""
    items = value if isinstance(value, tuple) else (value,)
    return ",".join(_scalar_text(vtype.base, item) for item in items)


def values_text(nodes: Iterable[Typed], values: Mapping[str, Value]) -> list[str]:
    """`name=value` for each of `nodes` that `values` holds, in the order of `nodes`."""
    return [f"{n.name}={value_text(n.type, values[n.name])}" for n in nodes if n.name in values]


def _scalar_text(base: DataType, item: Scalar) -> str:
    if isinstance(item, str):
        return item.translate(_CONTROLS)
    return format_value_text(base, item)
