"""The robot model as the RSP layers (`rsp`) read it: what a set bit of a Device Map brings, by
device kind (D-RSP-14), how each field's value is read and written (D-RCML-9 to D-RCML-11), and
a model's `ModelLayout` (its ID, ID length, and devices in model order).

Like the layers, a second reading of the wire format, apart from ``rcmlconf.rsp.codec``: only the
robot model itself is shared.
"""

from __future__ import annotations

import struct
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, NamedTuple

if TYPE_CHECKING:
    from rcmlconf.rsp.model import RobotModel

#: D-RSP-14: what a set bit brings, by device kind, in DOWNLINK, UPLINK and ACK. "flag": nothing
#: (a request, a module's activation); "state": the fields; "occurrence": an ID then the fields;
#: "id": an acknowledged occurrence's ID; None: the bit is never set.
RSP_BITS: dict[str, tuple[str | None, str | None, str | None]] = {
    "effector": ("state", None, None),
    "sensor": ("flag", "state", None),
    "monitor": ("flag", "state", None),
    "module": ("flag", None, None),
    "command": ("occurrence", None, "id"),
    "event": ("flag", "occurrence", None),
    "memoryCommand": ("occurrence", None, "id"),
    "memoryEvent": ("flag", "occurrence", "id"),
}

#: D-RCML-9: the struct code of each fixed-size type; string and bytes are a 16-bit length and
#: that many bytes.
RSP_VALUE_CODES = {
    "bool": "B",
    "int8": "b",
    "uint8": "B",
    "int16": "h",
    "uint16": "H",
    "int32": "i",
    "uint32": "I",
    "int64": "q",
    "uint64": "Q",
    "float32": "f",
    "float64": "d",
}


class CutShort(Exception):
    """A value runs past the end of the datagram."""


#: (datagram, position) -> (value, position after it).
_Decode = Callable[[bytes, int], tuple[Any, int]]
#: value -> its bytes.
_Encode = Callable[[Any], bytes]


def _bool(byte: int) -> bool | int:
    # 0x00 and 0x01 only (R-RCML-30): any other byte is shown as the number it is.
    return {0: False, 1: True}.get(byte, byte)


def _value_codec(type_name: str, count: int) -> tuple[_Decode, _Encode]:
    """How one field's value is read and written (D-RCML-10, D-RCML-11)."""
    if type_name in ("string", "bytes"):
        text = type_name == "string"

        def decode_sized(data: bytes, pos: int) -> tuple[Any, int]:
            items: list[Any] = []
            for _ in range(count):
                if pos + 2 > len(data):
                    raise CutShort
                length = int.from_bytes(data[pos : pos + 2], "big")
                pos += 2
                if pos + length > len(data):
                    raise CutShort
                raw = data[pos : pos + length]
                pos += length
                if text:
                    try:
                        items.append(raw.decode("utf-8"))
                    except UnicodeDecodeError:
                        items.append(raw)  # not UTF-8 (R-RCML-30): the bytes as they are
                else:
                    items.append(raw)
            return (items[0] if count == 1 else tuple(items)), pos

        def encode_sized(value: Any) -> bytes:
            out = b""
            for item in (value,) if count == 1 else value:
                raw = item.encode("utf-8") if isinstance(item, str) else bytes(item)
                out += struct.pack("!H", len(raw)) + raw
            return out

        return decode_sized, encode_sized
    code = RSP_VALUE_CODES[type_name]
    layout = struct.Struct(f"!{count}{code}")
    is_bool = type_name == "bool"

    def decode_fixed(data: bytes, pos: int) -> tuple[Any, int]:
        if pos + layout.size > len(data):
            raise CutShort
        values = layout.unpack_from(data, pos)
        if is_bool:
            values = tuple(_bool(v) for v in values)
        return (values[0] if count == 1 else values), pos + layout.size

    def encode_fixed(value: Any) -> bytes:
        return layout.pack(*((value,) if count == 1 else value))

    return decode_fixed, encode_fixed


class _FieldLayout(NamedTuple):
    name: str
    decode: _Decode
    encode: _Encode


class _DeviceLayout(NamedTuple):
    position: int
    name: str
    kind: str
    fields: tuple[_FieldLayout, ...]
    #: What a set bit brings in DOWNLINK, UPLINK, ACK (RSP_BITS).
    bits: tuple[str | None, str | None, str | None]


class ModelLayout(NamedTuple):
    """What the layer needs of a robot model: its ID, ID length, and devices in model order."""

    name: str
    model_id: int
    id_length: int
    devices: tuple[_DeviceLayout, ...]

    @property
    def map_size(self) -> int:
        return (len(self.devices) + 7) // 8

    @classmethod
    def of(cls, model: RobotModel) -> ModelLayout:
        devices = []
        for device in model.devices:
            fields = tuple(
                _FieldLayout(f.name, *_value_codec(f.type.base.name, f.type.count))
                for f in device.fields
            )
            kind = device.kind.value
            bits = RSP_BITS[kind]
            devices.append(_DeviceLayout(device.position, device.name, kind, fields, bits))
        return cls(model.name, model.model_id, model.id_length, tuple(devices))
