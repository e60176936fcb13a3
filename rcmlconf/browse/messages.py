"""The page's protocol over the WebSocket (docs/browse.md): JSON objects, each with `"v": 1`.

The page is trusted no more than a network peer: a message is at most MAX_MESSAGE bytes, must be
an object of the version and a known type, and may name only a widget of the panel that does what
the message asks (an input to a widget that writes, an action to an actionButton). Anything else
is refused with the reason, which the bridge logs and tells the page; nothing it sends can raise.
"""

from __future__ import annotations

import json
from dataclasses import dataclass

from rcmlconf.browse.panel import PanelWidget
from rcmlconf.errors import RcmlconfError

VERSION = 1
#: The longest message the page may send: an input's value is one scalar (D-RXID-6), a string
#: node's at most 65,535 bytes as text, escaped in JSON at most six characters a byte.
MAX_MESSAGE = 400_000
#: What a button or a checkbox sends as its value (the bridge knows what each writes).
BUTTON_INPUTS = ("press", "release")
CHECKBOX_INPUTS = ("on", "off")


class Malformed(RcmlconfError):
    """A message of the page that is refused; the text says why."""


@dataclass(frozen=True, slots=True)
class Input:
    """The user changed a writing widget: `value` is its text (D-RCML-14), or one of
    BUTTON_INPUTS or CHECKBOX_INPUTS."""

    widget: PanelWidget
    value: str


@dataclass(frozen=True, slots=True)
class Action:
    """The user pressed an actionButton (D-RXID-7)."""

    widget: PanelWidget


def parse_message(data: str | bytes, widgets: dict[str, PanelWidget]) -> Input | Action:
    if len(data) > MAX_MESSAGE:
        raise Malformed(f"a message of {len(data):,} bytes (at most {MAX_MESSAGE:,})")
    if isinstance(data, bytes):
        raise Malformed("a binary message (the protocol is JSON text)")
    try:
        message = json.loads(data)
    except (ValueError, RecursionError) as exc:
        raise Malformed(f"not JSON: {exc}") from None
    if not isinstance(message, dict):
        raise Malformed("not a JSON object")
    if message.get("v") != VERSION:
        raise Malformed(f"version {message.get('v')!r}, not {VERSION}")
    kind, key = message.get("type"), message.get("widget")
    if kind not in ("input", "action"):
        raise Malformed(f"type {_short(kind)} is none of input, action")
    widget = widgets.get(key) if isinstance(key, str) else None
    if widget is None:
        raise Malformed(f"widget {_short(key)} is none of the panel's")
    if kind == "action":
        if widget.kind != "actionButton":
            raise Malformed(f"{key} is a {widget.kind}, not an actionButton")
        return Action(widget)
    value = message.get("value")
    if not isinstance(value, str):
        raise Malformed(f"{key}'s value {_short(value)} is not a string")
    if widget.link is None or not widget.link.writes:
        raise Malformed(f"{key} ({widget.kind}) writes nothing")
    allowed = {"button": BUTTON_INPUTS, "checkbox": CHECKBOX_INPUTS}.get(widget.kind)
    if allowed is not None and value not in allowed:
        raise Malformed(f"a {widget.kind} sends one of {', '.join(allowed)}, not {_short(value)}")
    return Input(widget, value)


def _short(value: object) -> str:
    """A value of the page's in a log line: its JSON, cut short."""
    text = json.dumps(value)
    return text if len(text) <= 40 else text[:37] + "..."


# -- what the bridge sends ---------------------------------------------------------------------


def message(kind: str, **fields: object) -> dict[str, object]:
    return {"v": VERSION, "type": kind, **fields}
