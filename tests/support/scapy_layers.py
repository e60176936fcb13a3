"""What the core reader and the scapy RCTP layer read in a control-connection stream, as plain
values, so that tests can compare the two."""

from __future__ import annotations

from typing import Any

from scapy.packet import Packet, Padding, Raw

from rcmlconf.rctp.errors import RemoteProtocolError
from rcmlconf.rctp.messages import Request
from rcmlconf.rctp.reader import MessageReader
from rcmlconf.scapy_layers import rctp


def core_messages(data: bytes) -> tuple[list[dict[str, Any]], int | None]:
    """The messages the core reader frames in a stream, and where it stopped (None: the end)."""
    reader = MessageReader()
    reader.feed(data)
    found = []
    while True:
        try:
            message = reader.next_message()
        except RemoteProtocolError:
            return found, reader.offset
        if message is None:
            return found, None if not reader.buffered else reader.offset
        if isinstance(message, Request):
            start = {"method": message.method, "target": message.target}
        else:
            start = {"status": message.status, "reason": message.reason}
        found.append(
            {
                **start,
                "version": message.version,
                "headers": list(message.headers.fields),
                "body": message.body,
            }
        )


def layer_message(layer: Packet) -> dict[str, Any]:
    if isinstance(layer, rctp.RCTPRequest):
        start = {"method": layer.method.decode(), "target": layer.target.decode("latin-1")}
    else:
        assert isinstance(layer, rctp.RCTPResponse), layer
        start = {"status": layer.status, "reason": layer.reason.decode("latin-1")}
    return {
        **start,
        "version": layer.version.decode(),
        "headers": list(layer.headers),
        "body": layer.body,
    }


def layer_messages(packet: Packet) -> tuple[list[dict[str, Any]], Packet | None]:
    """The messages of a dissected chain, and what follows them (Raw), if anything."""
    found = []
    layer: Packet | None = packet
    while layer:
        if isinstance(layer, Raw | Padding):
            return found, layer
        if type(layer) is rctp.RCTP:  # no bytes at all
            break
        found.append(layer_message(layer))
        layer = layer.payload
    return found, None
