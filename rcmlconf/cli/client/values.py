"""Values as a person types and reads them on the command line (D-RCML-14), and as JSON.

A value's text is `rcmlconf.values`' (`parse_value_text`, `format_value_text`); a string is
shown with its control characters escaped, for the terminal's sake. An array is its items joined
by commas, so an array of strings holding a comma cannot be typed; JSON output
shows every value exactly.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence

from rcmlconf.errors import ValueTextError
from rcmlconf.rcml.model import AccessNode, DataNode
from rcmlconf.rctp.bodies import Typed
from rcmlconf.values import (
    DataType,
    Kind,
    Scalar,
    Value,
    ValueType,
    format_value_text,
    parse_value_text,
    shown,
)

_LONGEST_REASON = 200


def parse_node_value(node: DataNode, text: str) -> Value:
    """The value of `node` typed as `text`: its text form, an array's items comma-separated."""
    return parse_typed_value(node.type, text, node.path)


def parse_typed_value(vtype: ValueType, text: str, where: str) -> Value:
    """A value of `vtype` typed as `text` (an RCML data node's, an RSP field's); errors name
    `where`."""
    try:
        if not vtype.is_array:
            return parse_value_text(vtype.base, text, vtype.size)
        items = text.split(",")
        if len(items) != vtype.count:
            raise ValueTextError(f"{vtype.count} comma-separated items needed, not {len(items)}")
        # Spaces after commas are read as part of a string, and skipped in any other type.
        if vtype.base.kind is not Kind.STRING:
            items = [item.strip(" ") for item in items]
        return tuple(parse_value_text(vtype.base, item, vtype.size) for item in items)
    except ValueTextError as exc:
        raise ValueTextError(f"{where} ({vtype}): {_one_line(str(exc))}") from None


def _one_line(reason: str) -> str:
    """A reason that quotes a long value, with the value's middle left out: the error names the
    value and says what is wrong with it on one line a person can read."""
    if len(reason) <= _LONGEST_REASON:
        return reason
    return f"{reason[: _LONGEST_REASON // 2]} ... {reason[-_LONGEST_REASON // 2 :]}"


def parse_assignments(access: AccessNode, texts: Sequence[str]) -> dict[str, Value]:
    """`name=value ...` for data nodes of `access`, each named once."""
    by_name = {node.name: node for node in access.data}
    values: dict[str, Value] = {}
    for text in texts:
        name, equals, value = text.partition("=")
        if not equals:
            raise ValueTextError(f"{text!r} is not name=value")
        node = by_name.get(name)
        if node is None:
            raise ValueTextError(
                f"{access.path} has no data node {name!r} (it has {', '.join(by_name)})"
            )
        if name in values:
            raise ValueTextError(f"{name} is given twice")
        values[name] = parse_node_value(node, value)
    return values


def value_text(node: Typed, value: Value) -> str:
    """The text form of a value of `node` (D-RCML-14), readable back by `parse_node_value`."""
    return shown.value_text(node.type, value)


def value_json(node: Typed, value: Value) -> object:
    """A JSON value: numbers as numbers (a float32 with its shortest digits), bytes as hex,
    and INF, -INF and NaN as those strings, since JSON has no such numbers."""
    items = [_scalar_json(node.type.base, item) for item in _items(value)]
    return items if node.type.is_array else items[0]


def values_json(nodes: Iterable[Typed], values: Mapping[str, Value]) -> dict[str, object]:
    return {n.name: value_json(n, values[n.name]) for n in nodes if n.name in values}


def _items(value: Value) -> tuple[Scalar, ...]:
    return value if isinstance(value, tuple) else (value,)


def _scalar_json(base: DataType, item: Scalar) -> object:
    if isinstance(item, float):
        text = format_value_text(base, item)
        return float(text) if math.isfinite(item) else text
    if isinstance(item, bytes):
        return item.hex()
    return item
