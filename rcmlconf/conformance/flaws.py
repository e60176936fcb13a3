"""Malformed and out-of-range encodings of one value, made from the type table of
specs/rcml-2.0.md (D-RCML-9 to D-RCML-12): what the value cases send a server in WRITE bodies and
DATA payloads (R-RCTP-28, R-RCTP-58) and a robot in DOWNLINK payloads (R-RSP-18).

A `Flaw` is one way a value breaks the binary value format or its node's declaration. `flawed`
makes a holder's encodings of a flaw (an RCML data node's, an RSP field's) from its type, `count`,
`size`, `min` and `max`, by rule rather than by type: a bool byte other than 0x00 and 0x01 for
any bool, a length above `size` for any string or bytes, a number past each bound declared for
any number. Each encoding stands for the holder's whole value; in an array the flaw is in the last
item and the items before it are valid, since the rules hold for every item (D-RCML-11, D-RCML-12).
"""

from __future__ import annotations

import enum
import math
import struct
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Protocol

from rcmlconf.values import Kind, Scalar, Value, ValueType
from rcmlconf.values.binary import encode_value
from rcmlconf.values.types import MAX_SIZE

_LENGTH = struct.Struct(">H")
_FLOAT32 = struct.Struct(">f")
#: The bool bytes sent: the first past true, and the last a byte can hold.
_BOOL_BYTES = (0x02, 0xFF)
#: Byte runs no UTF-8 decoder takes: a byte never in UTF-8, a lead byte without its continuation.
_NOT_UTF8 = (b"\xff", b"\xc3\x28")
#: The length a value cut short claims, at most (its last byte is missing).
_CUT_LENGTH = 4


class Holder(Protocol):
    """What holds a value of a declared type: an RCML data node, an RSP field."""

    @property
    def name(self) -> str: ...

    @property
    def type(self) -> ValueType: ...

    @property
    def minimum(self) -> int | float | None: ...

    @property
    def maximum(self) -> int | float | None: ...


class Flaw(enum.Enum):
    BOOL_BYTE = "bool-byte"
    OVER_SIZE = "over-size"
    NOT_UTF8 = "not-utf8"
    PAST_END = "past-end"
    ITEM_COUNT = "item-count"
    OUT_OF_RANGE = "out-of-range"
    NAN = "nan"

    @property
    def malformed(self) -> bool:
        """The value does not decode (R-RCML-30, D-RCML-11); else it decodes to a number outside
        its holder's range (D-RCML-12)."""
        return self not in (Flaw.OUT_OF_RANGE, Flaw.NAN)

    @property
    def about(self) -> str:
        """What the flawed value is, for a case's purpose."""
        return _ABOUT[self][0]

    @property
    def needs(self) -> str:
        """What a holder needs to have the flaw, for a not-applicable verdict."""
        return _ABOUT[self][1]


_ABOUT: dict[Flaw, tuple[str, str]] = {
    Flaw.BOOL_BYTE: ("a bool byte other than 0x00 and 0x01", "of type bool"),
    Flaw.OVER_SIZE: (
        "a string or bytes longer than its size",
        "of type string or bytes with a size below 65,535",
    ),
    Flaw.NOT_UTF8: ("a string that is not UTF-8", "of type string"),
    Flaw.PAST_END: ("a string or bytes whose length runs past its end", "of type string or bytes"),
    Flaw.ITEM_COUNT: ("an array of one item too few or too many", "that is an array"),
    Flaw.OUT_OF_RANGE: ("a number outside its min or max", "of a number type with min or max"),
    Flaw.NAN: ("NaN where min or max is declared", "of a floating-point type with min or max"),
}


@dataclass(frozen=True, slots=True)
class Bad:
    """One flawed encoding of a holder's value."""

    flaw: Flaw
    #: The bytes sent in place of the holder's value.
    data: bytes
    #: What is wrong with them, for the transcript and a failure.
    what: str
    #: The value a receiver that let the flaw through would take, when there is one: a valid
    #: value other than it, written before, shows whether the flawed one was applied.
    lenient: Value | None


def flawed(holder: Holder, flaw: Flaw) -> list[Bad]:
    """The encodings of `holder`'s value with `flaw`; none when its declaration cannot have it."""
    return _MAKERS[flaw](holder)


def has(holder: Holder, flaw: Flaw) -> bool:
    return bool(flawed(holder, flaw))


def spliced(
    holders: Sequence[Holder],
    values: Mapping[str, Value],
    bad: Holder | None = None,
    data: bytes = b"",
) -> bytes:
    """The values of `holders` one after another (D-RCML-10), `data` in place of `bad`'s."""
    return b"".join(
        data if bad is not None and h.name == bad.name else encode_value(h.type, values[h.name])
        for h in holders
    )


# -- the valid items around a flawed one -----------------------------------------------------------


def _one(holder: Holder) -> ValueType:
    return ValueType(holder.type.base, 1, holder.type.size)


def _bounds(holder: Holder) -> tuple[float, float]:
    low = -math.inf if holder.minimum is None else float(holder.minimum)
    high = math.inf if holder.maximum is None else float(holder.maximum)
    return low, high


def _valid_item(holder: Holder) -> Scalar:
    """An item of the holder's type within its range: 0 or the bound nearest it, false, empty."""
    kind = holder.type.base.kind
    low, high = _bounds(holder)
    if kind is Kind.INTEGER:
        return int(min(max(0.0, low), high))  # integer bounds: the nearest is an integer
    if kind is Kind.FLOAT:
        return min(max(0.0, low), high)
    return _BLANK[kind]


_BLANK: dict[Kind, Scalar] = {Kind.BOOL: False, Kind.STRING: "", Kind.BYTES: b""}


def _items(holder: Holder, count: int) -> bytes:
    """`count` valid items."""
    return encode_value(_one(holder), _valid_item(holder)) * count


def _last(holder: Holder, item: Scalar) -> Value:
    """The value whose last item is `item`, the others valid."""
    count = holder.type.count
    return (*[_valid_item(holder)] * (count - 1), item) if count > 1 else item


def _bad(holder: Holder, flaw: Flaw, last: bytes, what: str, lenient: Scalar | None) -> Bad:
    """The value with `last` as its last item's encoding."""
    count = holder.type.count
    where = f" in item {count} of {count}" if count > 1 else ""
    value = None if lenient is None else _last(holder, lenient)
    return Bad(flaw, _items(holder, count - 1) + last, what + where, value)


# -- the flaws -------------------------------------------------------------------------------------


def _bool_byte(holder: Holder) -> list[Bad]:
    if holder.type.base.kind is not Kind.BOOL:
        return []
    flaw = Flaw.BOOL_BYTE
    return [_bad(holder, flaw, bytes([b]), f"bool byte 0x{b:02x}", True) for b in _BOOL_BYTES]


def _text(holder: Holder, raw: bytes) -> Scalar:
    return raw.decode() if holder.type.base.kind is Kind.STRING else raw


def _over_size(holder: Holder) -> list[Bad]:
    size = holder.type.size
    if not holder.type.base.sized or size >= MAX_SIZE:
        return []
    raw = b"a" * (size + 1)
    what = f"length {size + 1} above size {size}"
    return [_bad(holder, Flaw.OVER_SIZE, _LENGTH.pack(len(raw)) + raw, what, _text(holder, raw))]


def _not_utf8(holder: Holder) -> list[Bad]:
    if holder.type.base.kind is not Kind.STRING:
        return []
    return [
        _bad(holder, Flaw.NOT_UTF8, _LENGTH.pack(len(raw)) + raw, f"bytes {raw.hex()}", None)
        for raw in _NOT_UTF8
        if len(raw) <= holder.type.size
    ]


def _past_end(holder: Holder) -> list[Bad]:
    if not holder.type.base.sized:
        return []
    length = min(holder.type.size, _CUT_LENGTH)
    raw = b"a" * (length - 1)
    what = f"length {length} with {len(raw)} bytes after it"
    return [_bad(holder, Flaw.PAST_END, _LENGTH.pack(length) + raw, what, _text(holder, raw))]


def _item_count(holder: Holder) -> list[Bad]:
    count = holder.type.count
    if count < 2:
        return []
    return [
        Bad(Flaw.ITEM_COUNT, _items(holder, n), f"{n} items where count is {count}", None)
        for n in (count - 1, count + 1)
    ]


def _beyond(holder: Holder, bound: float, sign: int) -> list[Scalar]:
    """Items of the holder's type past `bound` (above it for `sign` 1, below for -1): the next
    integer, or a float well past it and infinity."""
    base = holder.type.base
    if base.kind is Kind.INTEGER:
        item = math.floor(bound) + 1 if sign > 0 else math.ceil(bound) - 1
        return [item] if base.low <= item <= base.high else []
    past = bound + sign * max(1.0, abs(bound))
    if base.name == "float32":
        try:
            past = _FLOAT32.unpack(_FLOAT32.pack(past))[0]
        except OverflowError:
            past = math.inf
    return [*([past] if math.isfinite(past) else []), sign * math.inf]


def _out_of_range(holder: Holder) -> list[Bad]:
    if not holder.type.base.numeric:
        return []
    found = []
    for bound, sign, side in ((holder.maximum, 1, "above max"), (holder.minimum, -1, "below min")):
        if bound is None:
            continue
        for item in _beyond(holder, bound, sign):
            data = encode_value(_one(holder), item)
            found.append(_bad(holder, Flaw.OUT_OF_RANGE, data, f"{item!r} {side} {bound}", item))
    return found


def _nan(holder: Holder) -> list[Bad]:
    declared = holder.minimum is not None or holder.maximum is not None
    if holder.type.base.kind is not Kind.FLOAT or not declared:
        return []
    data = encode_value(_one(holder), math.nan)
    return [_bad(holder, Flaw.NAN, data, "NaN", math.nan)]


_MAKERS = {
    Flaw.BOOL_BYTE: _bool_byte,
    Flaw.OVER_SIZE: _over_size,
    Flaw.NOT_UTF8: _not_utf8,
    Flaw.PAST_END: _past_end,
    Flaw.ITEM_COUNT: _item_count,
    Flaw.OUT_OF_RANGE: _out_of_range,
    Flaw.NAN: _nan,
}
