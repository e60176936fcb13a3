"""The RSP codec (specs/rsp.md §2, §3): pull_*/push_* pairs over bytes, derived from a robot model.

- `header`: the 20-byte header of Table II and the packet types (D-RSP-10, D-RSP-11).
- `bodies`: the session bodies (HELLO ... PERIOD) and `Item`, what one Device Map bit brings.
- `payloads`: one device's payload in one packet type, value by value (the reference path).
- `flat`: the payloads of a whole packet as one struct when they all have fixed sizes, read and
  written by code compiled for the map.
- `maps`: a Device Map and its payloads; `packets`: `RspCodec`, whole packets of one model.
"""

from rcmlconf.rsp.codec.bodies import (
    Bye,
    ByeReason,
    Hello,
    Item,
    MapBody,
    Packet,
    Period,
    Refused,
    RefusedReason,
    Welcome,
)
from rcmlconf.rsp.codec.header import (
    CLEAR_BUFFER,
    Encryption,
    Header,
    PacketType,
    pull_header,
    push_header,
)
from rcmlconf.rsp.codec.packets import RspCodec, codec_for

__all__ = [
    "CLEAR_BUFFER",
    "Bye",
    "ByeReason",
    "Encryption",
    "Header",
    "Hello",
    "Item",
    "MapBody",
    "Packet",
    "PacketType",
    "Period",
    "Refused",
    "RefusedReason",
    "RspCodec",
    "Welcome",
    "codec_for",
    "pull_header",
    "push_header",
]
