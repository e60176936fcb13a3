"""The data types of RCML 2.0 (D-RCML-9) and the full type of a data node (D-RCML-11)."""

from __future__ import annotations

import enum
from dataclasses import dataclass, field

#: A single value as Python holds it.
Scalar = bool | int | float | str | bytes
#: A data node's value: a scalar, or a tuple of `count` scalars for an array.
Value = Scalar | tuple[Scalar, ...]


class Kind(enum.Enum):
    BOOL = "bool"
    INTEGER = "integer"
    FLOAT = "float"
    STRING = "string"
    BYTES = "bytes"


@dataclass(frozen=True, slots=True)
class DataType:
    """One row of D-RCML-9's table."""

    name: str
    kind: Kind
    #: `struct` code of a fixed-size type ("" for string and bytes).
    code: str
    #: Encoded size of a fixed-size type; for string and bytes, the size of the length prefix.
    width: int
    #: Range of an integer type (both ends included).
    low: int = 0
    high: int = 0
    #: Integer or floating point (derived from `kind`; a field because it is asked per node).
    numeric: bool = field(init=False)
    #: Values have a length bounded by the node's `size` (string, bytes).
    sized: bool = field(init=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "numeric", self.kind in (Kind.INTEGER, Kind.FLOAT))
        object.__setattr__(self, "sized", self.kind in (Kind.STRING, Kind.BYTES))


def _int(name: str, code: str, width: int, signed: bool) -> DataType:
    bits = width * 8
    low, high = (-(1 << (bits - 1)), (1 << (bits - 1)) - 1) if signed else (0, (1 << bits) - 1)
    return DataType(name, Kind.INTEGER, code, width, low, high)


#: Canonical type name -> type.
DATA_TYPES: dict[str, DataType] = {
    t.name: t
    for t in (
        DataType("bool", Kind.BOOL, "B", 1),
        _int("int8", "b", 1, signed=True),
        _int("uint8", "B", 1, signed=False),
        _int("int16", "h", 2, signed=True),
        _int("uint16", "H", 2, signed=False),
        _int("int32", "i", 4, signed=True),
        _int("uint32", "I", 4, signed=False),
        _int("int64", "q", 8, signed=True),
        _int("uint64", "Q", 8, signed=False),
        DataType("float32", Kind.FLOAT, "f", 4),
        DataType("float64", Kind.FLOAT, "d", 8),
        DataType("string", Kind.STRING, "", 2),
        DataType("bytes", Kind.BYTES, "", 2),
    )
}

#: Alias -> canonical name. `int` is 32 bits, as on the paper's platforms (§9).
ALIASES: dict[str, str] = {"int": "int32", "float": "float32", "double": "float64"}


def lookup_type(name: str) -> DataType | None:
    """The type a `data/@type` value names, aliases included; None for an unknown name."""
    return DATA_TYPES.get(ALIASES.get(name, name))


#: Largest `count` and `size` (D-RCML-11).
MAX_COUNT = 65535
MAX_SIZE = 65535


@dataclass(frozen=True, slots=True)
class ValueType:
    """A data node's full type: its base type, `count` (array length) and `size` (max length)."""

    base: DataType
    count: int = 1
    #: Largest length in bytes of a string or bytes value; 0 for other types.
    size: int = 0

    @property
    def is_array(self) -> bool:
        return self.count > 1

    @property
    def max_encoded_size(self) -> int:
        """Bytes of the longest encoding of a value (D-RCML-13)."""
        one = self.base.width + self.size if self.base.sized else self.base.width
        return self.count * one

    def __str__(self) -> str:
        text = f"{self.base.name}({self.size})" if self.base.sized else self.base.name
        return f"{text}[{self.count}]" if self.is_array else text


def first_outside(
    value: Value, minimum: int | float | None, maximum: int | float | None
) -> int | None:
    """Index of the first item of `value` (a scalar is one item) outside `minimum`..`maximum`
    (D-RCML-12: every item of an array), or None. NaN is outside any range; a value with no bounds
    has none to break. Items that are not numbers are not compared.
    """
    if minimum is None and maximum is None:
        return None
    for index, item in enumerate(value if isinstance(value, tuple | list) else (value,)):
        if not isinstance(item, int | float) or isinstance(item, bool):
            continue
        # Written as "not within" so that NaN, which compares false, is outside too.
        if (minimum is not None and not item >= minimum) or (
            maximum is not None and not item <= maximum
        ):
            return index
    return None
