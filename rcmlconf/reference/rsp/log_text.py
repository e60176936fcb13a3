"""The reference robot's log as a person reads it (`rcmlconf robot -v`), not Python's reprs:
session IDs in the 12 hex digits `rcmlconf local` and `dissect` print (D-RSP-10's 48 bits),
reasons by name, a device's values as FIELD=VALUE in their text form (D-RCML-14).

    session 0e9ac77f2456 opened with 127.0.0.1:40661, T = 20 ms
    beep #0 <- tone=440
    leftWheel <- speed=200
    session ended by the local system: closed
"""

from __future__ import annotations

from collections.abc import Mapping

from rcmlconf.rsp.model import RobotModel
from rcmlconf.rsp.session import events
from rcmlconf.values import DataType, Scalar, Value, format_value_text

#: Bytes shown of a bytes value (an image, audio samples): a line a value, not a screenful.
_BYTES_SHOWN = 16


def event_text(model: RobotModel, event: events.Event) -> str:
    """One line for an endpoint's event."""
    match event:
        case events.SessionOpened(session_id, period, peer):
            where = "" if peer is None else f" with {peer[0]}:{peer[1]}"
            return f"session {session_id:012x} opened{where}, T = {period * 1000:g} ms"
        case events.SessionClosed(reason, by_peer):
            who = "the local system" if by_peer else "the robot"
            return f"session ended by {who}: {reason.name.lower()}"
        case events.SessionRefused(reason):
            return "no answer to HELLO" if reason is None else f"refused: {_words(reason.name)}"
        case events.LinkLost():
            return "link lost: nothing from the local system for 25 periods (D-RSP-13)"
        case events.LinkRestored():
            return "link restored"
        case events.StateReceived(device, values, _):
            return f"{device} <- {values_text(model, device, values)}"
        case events.OccurrenceReceived(device, ident, values):
            return f"{device} #{ident} <- {values_text(model, device, values)}"
        case events.Acknowledged(device, ident, after):
            return f"{device} #{ident} acknowledged after {after * 1000:.1f} ms"
        case events.PacketDropped(reason, rule, offset):
            at = "" if offset is None else f" at byte {offset}"
            return f"dropped a packet{at}: {reason} [{rule}]"


def values_text(model: RobotModel, device: str, values: Mapping[str, Value]) -> str:
    """`field=value ...` in the device's field order; an array's items comma-separated."""
    found = model.device(device)
    fields = found.fields if found is not None else ()
    return " ".join(
        f"{f.name}={','.join(_item(f.type.base, item) for item in _items(values[f.name]))}"
        for f in fields
        if f.name in values
    )


def _items(value: Value) -> tuple[Scalar, ...]:
    return value if isinstance(value, tuple) else (value,)


def _item(base: DataType, item: Scalar) -> str:
    if isinstance(item, str):
        # A string a peer sent must not move the terminal's cursor or change its colours.
        return item if item.isprintable() else item.encode("unicode_escape").decode("ascii")
    if isinstance(item, bytes) and len(item) > _BYTES_SHOWN:
        return f"{item[:_BYTES_SHOWN].hex()}...({len(item)} bytes)"
    return format_value_text(base, item)


def _words(name: str) -> str:
    return name.lower().replace("_", " ")
