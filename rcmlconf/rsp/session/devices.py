"""Devices named by an application, checked against the model before anything is queued, so that
a bad name or value fails at the call (KeyError, TypeError, EncodeError) and never in a beat."""

from __future__ import annotations

from collections.abc import Collection, Mapping

from rcmlconf.rsp.codec import Item, PacketType, RspCodec
from rcmlconf.rsp.model import Device, DeviceKind
from rcmlconf.values import Value


def device(codec: RspCodec, name: str, kinds: Collection[DeviceKind], what: str) -> Device:
    found = codec.model.device(name)
    if found is None:
        raise KeyError(f"{codec.model.name} has no device {name!r}")
    if found.kind not in kinds:
        allowed = " or ".join(kind.value for kind in kinds)
        raise TypeError(f"{name} is a {found.kind.value}: only a {allowed} can {what}")
    return found


def check_values(
    codec: RspCodec, kind: PacketType, found: Device, values: Mapping[str, Value], ident: int | None
) -> dict[str, Value]:
    """The values as a packet of `kind` would carry them; EncodeError if it could not."""
    copied = dict(values)
    codec.check_item(kind, Item(found.position, ident, copied))
    return copied
