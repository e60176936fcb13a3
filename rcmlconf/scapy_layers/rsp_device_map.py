"""The Device Map of DOWNLINK, UPLINK and ACK and the payloads of its set bits (D-RSP-14), read
and written with a robot model's `ModelLayout`: one bit per device in model order, the first in
the most significant bit, then the payloads of the set bits in model order with nothing between
them. Where the payloads do not fit the layout the items stop, the last one saying why, and the
layers (`rsp`) leave the rest to scapy's ``Raw``.
"""

from __future__ import annotations

from typing import Any, NamedTuple

from rcmlconf.scapy_layers.rsp_model import CutShort, ModelLayout

#: The packets of RSP_BITS' columns, in order.
_COLUMNS = ("DOWNLINK", "UPLINK", "ACK")


class RSPItem(NamedTuple):
    """What one set bit of a Device Map brings (D-RSP-14)."""

    position: int
    #: The device's name; "bit N" for a bit past the model's last device.
    device: str
    #: An occurrence's ID, or the ID an ACK acknowledges; else None.
    id: int | None = None
    #: A state's or an occurrence's fields by name; else None.
    values: dict[str, Any] | None = None
    #: Why the payloads stop here: what follows is left undecoded (``Raw``).
    note: str | None = None


def set_bits(number: int, size: int) -> list[int]:
    """The set bits of a Device Map of `size` bytes, as device positions in model order."""
    width = 8 * size
    return [width - 1 - bit for bit in range(width - 1, -1, -1) if number >> bit & 1]


def read_payloads(
    layout: ModelLayout, column: int, device_map: int, s: bytes
) -> tuple[bytes, list[RSPItem]]:
    """The items of the set bits of `device_map`, read from `s` as packets of RSP_BITS' `column`
    bring them; and the bytes after them."""
    items: list[RSPItem] = []
    pos = 0
    ident_size = layout.id_length
    for position in set_bits(device_map, layout.map_size):
        if position >= len(layout.devices):
            items.append(RSPItem(position, f"bit {position}", note="no such device"))
            break
        device = layout.devices[position]
        meaning = device.bits[column]
        if meaning is None:
            note = f"never set in {_COLUMNS[column]} (D-RSP-14)"
            items.append(RSPItem(position, device.name, note=note))
            break
        start = pos
        try:
            ident = None
            if meaning in ("occurrence", "id"):
                if pos + ident_size > len(s):
                    raise CutShort
                ident = int.from_bytes(s[pos : pos + ident_size], "big")
                pos += ident_size
            values = None
            if meaning in ("state", "occurrence"):
                values = {}
                for field in device.fields:
                    values[field.name], pos = field.decode(s, pos)
        except CutShort:
            pos = start
            items.append(RSPItem(position, device.name, note="cut short"))
            break
        items.append(RSPItem(position, device.name, ident, values))
    return s[pos:], items


def write_payloads(layout: ModelLayout, items: list[RSPItem] | None) -> bytes:
    """The payloads of `items` (those past the model's devices, or with a note, left out)."""
    out: list[bytes] = []
    for item in items or []:
        if item.note is not None or item.position >= len(layout.devices):
            continue
        device = layout.devices[item.position]
        if item.id is not None:
            out.append(item.id.to_bytes(layout.id_length, "big"))
        if item.values is not None:
            out.extend(field.encode(item.values[field.name]) for field in device.fields)
    return b"".join(out)


def _show_value(value: Any) -> str:
    if isinstance(value, bytes):
        shown = value[:16].hex()
        return f"0x{shown}..({len(value)} bytes)" if len(value) > 16 else f"0x{shown}"
    if isinstance(value, tuple):
        return "[" + ", ".join(_show_value(v) for v in value) + "]"
    return repr(value)


def show_item(item: RSPItem) -> str:
    """One item on one line: the device, its ID, its values and its note."""
    text = item.device
    if item.id is not None:
        text += f" #{item.id}"
    if item.values is not None:
        text += ": " + " ".join(f"{k}={_show_value(v)}" for k, v in item.values.items())
    if item.note is not None:
        text += f" [{item.note}]"
    return text
