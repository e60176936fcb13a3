"""What follows one set bit of a Device Map: a device's payload in one packet type (D-RSP-14).

A `Slot` is made once per device and map packet type. It reads and writes its payload value by
value: the reference, which every error message and offset comes from. `flat` reads and writes the
payloads of a whole packet with one struct when they all have fixed sizes, and leaves whatever it
doubts to the slots.

An occurrence's ID comes first (D-RSP-5), then the fields in document order (D-RSP-4), in the
binary value format (D-RCML-10); a field's `min` and `max` bound every item (D-RCML-12), and a value
outside them makes the packet malformed, as a value the format refuses does (R-RCML-30).
"""

from __future__ import annotations

import struct
from collections.abc import Mapping

from rcmlconf.buffer import Buffer
from rcmlconf.errors import EncodeError, ProtocolError
from rcmlconf.rctp.bodies import ValuesCodec
from rcmlconf.rsp.codec.bodies import RULE, Item
from rcmlconf.rsp.layout import Bit
from rcmlconf.rsp.model import Device, Field, RobotModel
from rcmlconf.values import Value, first_outside
from rcmlconf.values.binary import codec_for, encode_value

#: An occurrence's ID: 1 or 2 bytes (D-RSP-5), as struct codes.
ID_CODES = {1: "B", 2: "H"}


class Slot:
    """One device's payload in one kind of map packet: `layout.Bit` says what it holds."""

    __slots__ = (
        "_bounded",
        "_id",
        "_pullers",
        "device",
        "fields",
        "fixed",
        "has_id",
        "id_length",
        "meaning",
        "name",
        "values",
    )

    def __init__(self, model: RobotModel, device: Device, meaning: Bit) -> None:
        self.device = device.position
        self.name = device.name
        self.meaning = meaning
        self.has_id = meaning in (Bit.OCCURRENCE, Bit.ID)
        self.id_length = model.id_length
        self._id = struct.Struct(">" + ID_CODES[model.id_length])
        carries = meaning in (Bit.STATE, Bit.OCCURRENCE)
        self.fields: tuple[Field, ...] = device.fields if carries else ()
        self.values = (
            ValuesCodec(self.fields, device.name, RULE, canonical=False) if carries else None
        )
        #: Each field and how to read its value (D-RCML-10).
        self._pullers = tuple((field, codec_for(field.type)[0]) for field in self.fields)
        #: The fields with a range, and their places (D-RCML-12).
        self._bounded = tuple(
            (number, field)
            for number, field in enumerate(self.fields)
            if field.minimum is not None or field.maximum is not None
        )
        #: Every field has one size: `flat` can read and write the payload with a struct.
        self.fixed = not any(field.type.base.sized for field in self.fields)

    # -- the reference: value by value ---------------------------------------------------------

    def pull(self, buf: Buffer) -> Item:
        """The payload at the buffer's position; offsets in errors are the buffer's, and a
        payload cut short has no rule yet (the caller's)."""
        ident = buf.pull_struct(self._id)[0] if self.has_id else None
        if self.values is None:
            return Item(self.device, ident, None)
        values = {}
        # Field by field, each value's range checked as it is read: the first fault in the bytes
        # is the one reported.
        for field, pull in self._pullers:
            start = buf.position
            value = pull(buf)
            if field.minimum is not None or field.maximum is not None:
                index = first_outside(value, field.minimum, field.maximum)
                if index is not None:
                    item = value[index] if isinstance(value, tuple) else value
                    raise ProtocolError(
                        f"{field.name}: {item!r} is outside {field.minimum} to {field.maximum}",
                        start + index * field.type.base.width,
                        RULE,
                    )
            values[field.name] = value
        return Item(self.device, ident, values)

    def push(self, buf: Buffer, item: Item) -> None:
        if self.has_id:
            ident = item.id
            if not isinstance(ident, int) or isinstance(ident, bool):
                raise EncodeError(f"{self.name}: a {self.meaning.value} bit needs an ID")
            if not 0 <= ident < 1 << (8 * self.id_length):
                raise EncodeError(f"{self.name}: ID {ident} does not fit {self.id_length} bytes")
            buf.push_struct(self._id, ident)
        elif item.id is not None:
            raise EncodeError(f"{self.name}: a {self.meaning.value} bit carries no ID")
        if self.values is None:
            if item.values is not None:
                raise EncodeError(f"{self.name}: a {self.meaning.value} bit carries no values")
            return
        if not isinstance(item.values, Mapping):
            raise EncodeError(f"{self.name}: a {self.meaning.value} bit needs its values")
        self.values.push(buf, item.values)
        fault = self._out_of_range(item.values)
        if fault is not None:
            raise EncodeError(fault[0])

    def _out_of_range(self, values: Mapping[str, Value]) -> tuple[str, int] | None:
        """Why a value is outside its field's range (D-RCML-12), and the offset of the item at
        fault from the first field's; None when every value is within."""
        for number, field in self._bounded:
            value = values[field.name]
            index = first_outside(value, field.minimum, field.maximum)
            if index is not None:
                item = value[index] if isinstance(value, tuple | list) else value
                reason = (
                    f"{self.name}/{field.name}: {item!r} is outside {field.minimum} to"
                    f" {field.maximum}"
                )
                offset = sum(
                    len(encode_value(before.type, values[before.name]))
                    for before in self.fields[:number]
                )
                return reason, offset + index * field.type.base.width
        return None
