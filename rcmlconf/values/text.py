"""Values and numbers of seconds written as text (D-RCML-7, D-RCML-14), read and written.

Python's own `int()` and `float()` accept underscores, surrounding whitespace, non-ASCII digits,
`inf` and `nan` in any case; none of that is RCML, so every form is matched by a regular
expression before it is converted.
"""

from __future__ import annotations

import math
import re
import struct

from rcmlconf.errors import ValueTextError
from rcmlconf.values.types import DataType, Kind, Scalar

_INTEGER = re.compile(r"[+-]?[0-9]+")
# XML Schema 1.0 `double` lexical space.
_DOUBLE = re.compile(r"[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?|-?INF|NaN")
_POSITIVE = re.compile(r"\+?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")
_HEX = re.compile(r"(?:[0-9A-Fa-f]{2})*")
_BOOLEANS = {"true": True, "1": True, "false": False, "0": False}
_FLOAT32 = struct.Struct(">f")


def parse_positive(text: str) -> float:
    """A positive, finite decimal number (D-RCML-7): seconds such as `16e-3`, `0.016`, `10`."""
    if _POSITIVE.fullmatch(text) is None:
        raise ValueTextError(f"{text!r} is not a positive number (such as 0.016 or 16e-3)")
    value = float(text)
    if not 0 < value < math.inf:
        raise ValueTextError(f"{text!r} is not a positive, finite number")
    return value


def _parse_bool(base: DataType, text: str, size: int) -> Scalar:
    try:
        return _BOOLEANS[text]
    except KeyError:
        raise ValueTextError(f"{text!r} is not a bool (true, false, 1 or 0)") from None


def _parse_integer(base: DataType, text: str, size: int) -> Scalar:
    if _INTEGER.fullmatch(text) is None:
        raise ValueTextError(f"{text!r} is not a decimal integer")
    # Bound the digits first: int() refuses more than 4,300 digits with a ValueError.
    if len(text.lstrip("+-").lstrip("0")) > 20:
        raise ValueTextError(f"{text[:24]}... is outside the range of {base.name}")
    value = int(text)
    if not base.low <= value <= base.high:
        raise ValueTextError(
            f"{text} is outside the range of {base.name} ({base.low} to {base.high})"
        )
    return value


def _parse_float(base: DataType, text: str, size: int) -> Scalar:
    if _DOUBLE.fullmatch(text) is None:
        raise ValueTextError(f"{text!r} is not a floating-point number (such as 1.5, -2E3, INF)")
    value = float(text)
    if base.name == "float32":
        try:
            value = _FLOAT32.unpack(_FLOAT32.pack(value))[0]
        except OverflowError:
            raise ValueTextError(f"{text} is too large for float32") from None
    if math.isinf(value) and "INF" not in text:
        raise ValueTextError(f"{text} is too large for {base.name}")
    return value


def _parse_string(base: DataType, text: str, size: int) -> Scalar:
    length = len(text.encode("utf-8", "surrogatepass"))
    if length > size:
        raise ValueTextError(f"{text!r} is {length} bytes in UTF-8, longer than size {size}")
    return text


def _parse_bytes(base: DataType, text: str, size: int) -> Scalar:
    if _HEX.fullmatch(text) is None:
        raise ValueTextError(f"{text!r} is not hexadecimal bytes (two digits a byte)")
    value = bytes.fromhex(text)
    if len(value) > size:
        raise ValueTextError(f"{len(value)} bytes is longer than size {size}")
    return value


_PARSERS = {
    Kind.BOOL: _parse_bool,
    Kind.INTEGER: _parse_integer,
    Kind.FLOAT: _parse_float,
    Kind.STRING: _parse_string,
    Kind.BYTES: _parse_bytes,
}


def parse_value_text(base: DataType, text: str, size: int = 0) -> Scalar:
    """One value of `base` from its text form; `size` bounds string and bytes values."""
    return _PARSERS[base.kind](base, text, size)


def format_value_text(base: DataType, value: Scalar) -> str:
    """The text form of one value (D-RCML-14), which `parse_value_text` reads back: a float
    with the fewest digits that give it back in its type, so that 0.3 written as float32 is 0.3
    read, not 0.30000001192092896."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, bytes):
        return value.hex()
    if isinstance(value, float):
        return _float_text(base, value)
    return str(value)


def _float_text(base: DataType, value: float) -> str:
    if math.isnan(value):
        return "NaN"
    if math.isinf(value):
        return "INF" if value > 0 else "-INF"
    if base.name == "float32":
        for digits in range(1, 10):  # 9 significant digits always give a binary32 back
            shortest = float(f"{value:.{digits}g}")
            try:
                back = _FLOAT32.unpack(_FLOAT32.pack(shortest))[0]
            except OverflowError:  # rounded past the largest float32 (3.4028235e38)
                continue
            if back == value:
                return repr(shortest)  # Python's spelling, an XML Schema double: 2000.0
    return repr(value)
