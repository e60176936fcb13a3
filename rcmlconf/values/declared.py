"""A declared value: the `type`, `count`, `size`, `min` and `max` attributes that an RCML data
node (D-RCML-9 to D-RCML-13) and an RSP field (D-RSP-4) share, and what is wrong with them.

Problems name the RCML requirement they break (R-RCML-18, R-RCML-20, R-RCML-21); a language
that adopts these rules under a rule of its own (R-RSP-8) reports them under that one. Both
functions are cached: a document repeats few declarations, however many nodes it has.
"""

from __future__ import annotations

import math
from functools import lru_cache
from typing import NamedTuple

from rcmlconf.errors import ValueTextError
from rcmlconf.values.text import parse_value_text
from rcmlconf.values.types import Kind, Scalar, Value, ValueType, lookup_type

#: D-RCML-13: the largest encoding of one declared value.
MAX_VALUE_BYTES = 1024 * 1024

Number = int | float


class Problem(NamedTuple):
    """A finding about the declaration, to be reported at its element."""

    rule: str
    message: str
    #: The attribute it is about.
    attribute: str
    hint: str | None = None


@lru_cache(maxsize=4096)
def declared_type(
    type_name: str | None, count: int | None, size: int | None
) -> tuple[ValueType | None, tuple[Problem, ...]]:
    """The type these attribute values make, and what is wrong with them (R-RCML-18, -21).

    `type_name` is None or unknown when that was reported with the attribute: no type then.
    """
    base = lookup_type(type_name) if type_name is not None else None
    if base is None:
        return None, ()
    if base.sized and size is None:
        return None, (
            Problem(
                "R-RCML-18",
                f"{base.name} values need a size (1 to 65535)",
                "type",
                'add size="N", the largest length in bytes',
            ),
        )
    problems: list[Problem] = []
    if not base.sized and size is not None:
        problems.append(
            Problem(
                "R-RCML-18", f"{base.name} values take no size; only string and bytes do", "size"
            )
        )
    vtype = ValueType(base, count or 1, size if base.sized and size is not None else 0)
    if vtype.max_encoded_size > MAX_VALUE_BYTES:
        problems.append(
            Problem(
                "R-RCML-21",
                f"{vtype} encodes in up to {vtype.max_encoded_size:,} bytes, "
                f"more than {MAX_VALUE_BYTES:,}",
                "count",
            )
        )
    return vtype, tuple(problems)


@lru_cache(maxsize=4096)
def declared_bounds(
    vtype: ValueType, low_text: str | None, high_text: str | None
) -> tuple[Number | None, Number | None, tuple[Problem, ...]]:
    """`min` and `max` as values of the type, and what is wrong with them (R-RCML-20)."""
    problems: list[Problem] = []
    bounds: list[Number | None] = []
    for name, text in (("min", low_text), ("max", high_text)):
        value: Number | None = None
        if text is None:
            pass
        elif not vtype.base.numeric:
            problems.append(
                Problem(
                    "R-RCML-20", f"{name} applies to numbers only, not to {vtype.base.name}", name
                )
            )
        else:
            try:
                parsed = parse_value_text(vtype.base, text)
            except ValueTextError as exc:
                problems.append(Problem("R-RCML-20", f"{name}: {exc}", name))
            else:
                assert isinstance(parsed, int | float)
                if isinstance(parsed, float) and not math.isfinite(parsed):
                    problems.append(
                        Problem("R-RCML-20", f"{name} must be finite, not {text}", name)
                    )
                else:
                    value = parsed
        bounds.append(value)
    low, high = bounds
    if low is not None and high is not None and low > high:
        problems.append(Problem("R-RCML-20", f"min {low} is greater than max {high}", "min"))
    return low, high, tuple(problems)


_BLANK: dict[Kind, Scalar] = {Kind.BOOL: False, Kind.STRING: "", Kind.BYTES: b""}


def zero_value(vtype: ValueType, minimum: Number | None, maximum: Number | None) -> Value:
    """A declared value's zero (D-RSP-20, D-RCTP-31): the number nearest 0 within its range,
    false, or empty text or bytes; in every item of an array."""
    kind = vtype.base.kind
    item: Scalar
    if kind is Kind.INTEGER or kind is Kind.FLOAT:
        low = -math.inf if minimum is None else minimum
        high = math.inf if maximum is None else maximum
        nearest = min(max(0, low), high)
        item = float(nearest) if kind is Kind.FLOAT else int(nearest)
    else:
        item = _BLANK[kind]
    return tuple([item] * vtype.count) if vtype.is_array else item
