"""Devices named by an application, checked against the model before anything is queued, so that
a bad name or value fails at the call (KeyError, TypeError, EncodeError) and never in a beat."""

from __future__ import annotations

import math
from collections.abc import Collection, Mapping

from rcmlconf.rsp.codec import Item, PacketType, RspCodec
from rcmlconf.rsp.model import Device, DeviceKind
from rcmlconf.values import Value
from rcmlconf.wording import indefinite, one_of


def device(codec: RspCodec, name: str, kinds: Collection[DeviceKind], what: str) -> Device:
    found = codec.model.device(name)
    if found is None:
        raise KeyError(f"{codec.model.name} has no device {name!r}")
    if found.kind not in kinds:
        allowed = indefinite(one_of([kind.value for kind in kinds]))
        raise TypeError(f"{name} is {indefinite(found.kind.value)}: only {allowed} can {what}")
    return found


def check_values(
    codec: RspCodec, kind: PacketType, found: Device, values: Mapping[str, Value], ident: int | None
) -> dict[str, Value]:
    """The values as a packet of `kind` would carry them; EncodeError if it could not."""
    copied = dict(values)
    codec.check_item(kind, Item(found.position, ident, copied))
    return copied


#: Values of these types cannot change once made: one equal to a value held is that value.
_IMMUTABLE = frozenset({bool, int, str, bytes})


def same_values(held: Mapping[str, Value], values: Mapping[str, Value]) -> bool:
    """Whether `values` is what `held` holds, field for field, of the same types, each value
    immutable: what `check_values` of `values` would give again, with the same outcome. Only
    exactly equal: 1 and 1.0 and True, 0.0 and -0.0 are equal to Python but checked or encoded
    differently; NaN is equal to nothing, and a mutable value may have changed since."""
    if len(held) != len(values):
        return False
    for name, value in values.items():
        if name not in held or not _same(held[name], value):
            return False
    return True


def _same(held: Value, value: Value) -> bool:
    kind = type(value)
    if kind is not type(held):
        return False
    if kind is float:
        # Equal floats differ only by the sign of a zero, which float32 and float64 keep.
        return held == value and math.copysign(1.0, held) == math.copysign(1.0, value)  # type: ignore[arg-type]
    if kind is tuple:
        return len(held) == len(value) and all(map(_same, held, value))  # type: ignore[arg-type]
    return kind in _IMMUTABLE and held == value
