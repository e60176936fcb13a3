"""The binary value format (D-RCML-9 to D-RCML-11): big-endian, no tags, lengths only for text.

`pull_value` lets only `ProtocolError` escape (R-RCML-30); `push_value` raises `EncodeError` for a
local value that does not fit its type. Each node type gets one compiled codec, cached.
"""

from __future__ import annotations

import struct
from collections.abc import Callable
from functools import cache

from rcmlconf.buffer import Buffer
from rcmlconf.errors import EncodeError, ProtocolError
from rcmlconf.values.types import Kind, Scalar, Value, ValueType

_RULE = "R-RCML-30"

Puller = Callable[[Buffer], Value]
Pusher = Callable[[Buffer, Value], None]


def _check_scalar(vtype: ValueType, value: object) -> None:
    """Raise EncodeError unless `value` is a Python value of `vtype`'s base type."""
    base = vtype.base
    kind = base.kind
    if kind is Kind.INTEGER and isinstance(value, int) and not isinstance(value, bool):
        if not base.low <= value <= base.high:
            raise EncodeError(f"{value} is outside the range of {base.name}")
        return
    if kind is Kind.BOOL:
        ok = isinstance(value, bool)
    elif kind is Kind.INTEGER:
        ok = False
    elif kind is Kind.FLOAT:
        ok = isinstance(value, int | float) and not isinstance(value, bool)
    elif kind is Kind.STRING:
        ok = isinstance(value, str)
    else:
        ok = isinstance(value, bytes | bytearray)
    if not ok:
        raise EncodeError(f"{type(value).__name__} value {value!r} is not a {base.name}")


def _fixed_codec(vtype: ValueType) -> tuple[Puller, Pusher]:
    """Every element has the same size: one struct call reads or writes the whole value."""
    fmt = struct.Struct(f">{vtype.count}{vtype.base.code}")
    count = vtype.count
    is_bool = vtype.base.kind is Kind.BOOL

    def pull(buf: Buffer) -> Value:
        start = buf.position
        items = buf.pull_struct(fmt)
        if is_bool:
            for index, byte in enumerate(items):
                if byte > 1:
                    raise ProtocolError(
                        f"bool byte 0x{byte:02x} is neither 0x00 nor 0x01", start + index, _RULE
                    )
            items = tuple(byte == 1 for byte in items)
        return items if count > 1 else items[0]

    def push(buf: Buffer, value: Value) -> None:
        items = _items(vtype, value)
        for item in items:
            _check_scalar(vtype, item)
        try:
            buf.push_struct(fmt, *items)
        except (OverflowError, struct.error) as exc:
            raise EncodeError(f"{value!r} does not fit {vtype}: {exc}") from None

    return pull, push


def _sized_codec(vtype: ValueType) -> tuple[Puller, Pusher]:
    """string and bytes: a 16-bit length, then at most `size` bytes."""
    size = vtype.size
    count = vtype.count
    is_text = vtype.base.kind is Kind.STRING

    def pull_one(buf: Buffer) -> Scalar:
        start = buf.position
        length = buf.pull_uint16()
        if length > size:
            raise ProtocolError(f"length {length} exceeds size {size}", start, _RULE)
        raw = buf.pull_bytes(length)
        if not is_text:
            return raw
        try:
            return raw.decode("utf-8")
        except UnicodeDecodeError as exc:
            raise ProtocolError(
                f"string is not UTF-8: {exc.reason}", start + 2 + exc.start, _RULE
            ) from None

    def pull(buf: Buffer) -> Value:
        if count == 1:
            return pull_one(buf)
        return tuple(pull_one(buf) for _ in range(count))

    def push(buf: Buffer, value: Value) -> None:
        for item in _items(vtype, value):
            _check_scalar(vtype, item)
            raw = item.encode("utf-8") if isinstance(item, str) else item
            assert isinstance(raw, bytes | bytearray)  # _check_scalar saw to it
            if len(raw) > size:
                raise EncodeError(f"{len(raw)} bytes exceed size {size} of {vtype}")
            buf.push_uint16(len(raw))
            buf.push_bytes(raw)

    return pull, push


def _items(vtype: ValueType, value: Value) -> tuple[Value, ...]:
    if vtype.count == 1:
        return (value,)
    if not isinstance(value, tuple | list) or len(value) != vtype.count:
        raise EncodeError(f"{vtype} needs a sequence of {vtype.count} values, not {value!r}")
    return tuple(value)


@cache
def codec_for(vtype: ValueType) -> tuple[Puller, Pusher]:
    """The (pull, push) pair of a node type, built once."""
    return _sized_codec(vtype) if vtype.base.sized else _fixed_codec(vtype)


def pull_value(buf: Buffer, vtype: ValueType) -> Value:
    return codec_for(vtype)[0](buf)


def push_value(buf: Buffer, vtype: ValueType, value: Value) -> None:
    codec_for(vtype)[1](buf, value)


def encode_value(vtype: ValueType, value: Value) -> bytes:
    buf = Buffer()
    push_value(buf, vtype, value)
    return buf.data()


def decode_value(vtype: ValueType, data: bytes) -> Value:
    """Exactly one value: trailing bytes are malformed too."""
    buf = Buffer(data)
    value = pull_value(buf, vtype)
    if not buf.eof():
        raise ProtocolError(f"{buf.remaining} bytes after the {vtype} value", buf.position, _RULE)
    return value
