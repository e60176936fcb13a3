"""One RSP datagram as the probes read it (specs/rsp.md): the header's field offsets (D-RSP-10),
the `Datagram` record of one received and decoded, serial comparison of sequence numbers
(`newer`, D-RSP-15), and the one-line `summary` of a packet that the transcript shows. Both sides
use it: `rsp_probe.RspProbe` (the harness playing a local system) and `local_probe.LocalProbe`
(the harness playing a robot)."""

from __future__ import annotations

import struct
from collections.abc import Callable
from dataclasses import dataclass

from rcmlconf.rsp.codec import Bye, Header, Hello, Item, MapBody, PacketType, Refused, Welcome
from rcmlconf.rsp.codec.bodies import Body, Period
from rcmlconf.rsp.model import RobotModel
from rcmlconf.values import Value

#: Header field offsets (D-RSP-10).
VERSION_AT, MODEL_AT, ENCRYPTION_AT, TYPE_AT, SEQUENCE_AT = 0, 1, 3, 4, 5
TIMESTAMP_AT, SESSION_AT, LAST_AT, BUFFER_AT = 7, 11, 17, 19
#: How many sequence numbers there are (they wrap, D-RSP-15).
SEQUENCE_SPACE = 1 << 16
#: The header's fields, as `struct` reads and writes them.
HEADER_LAYOUT = struct.Struct(">BHBBHIHIHB")
#: Packet types whose body is never sealed (D-RSP-21).
UNSEALED = frozenset({PacketType.HELLO, PacketType.WELCOME, PacketType.REFUSED})


@dataclass(frozen=True, slots=True)
class Datagram:
    """One datagram from the robot, as the socket received it and the codec read it."""

    #: Loop time of its arrival.
    at: float
    data: bytes
    header: Header
    #: None when it is sealed with keys the probe does not have.
    body: Body | None

    @property
    def type(self) -> PacketType:
        return self.header.type

    @property
    def items(self) -> tuple[Item, ...]:
        """A map packet's items (empty for any other)."""
        return self.body.items if isinstance(self.body, MapBody) else ()

    def devices(self, model: RobotModel) -> set[str]:
        return {model.devices[item.device].name for item in self.items}

    def item(self, position: int) -> Item | None:
        return next((item for item in self.items if item.device == position), None)

    def acks(self, position: int) -> list[int]:
        """The IDs an ACK acknowledges for the device at `position`."""
        if self.type is not PacketType.ACK:
            return []
        return [item.id for item in self.items if item.device == position and item.id is not None]


Where = Callable[[Datagram], bool]


def newer(sequence: int, than: int) -> bool:
    """`sequence` is `than` or ahead of it by up to 32,767 (serial arithmetic, D-RSP-15)."""
    return (sequence - than) % SEQUENCE_SPACE < SEQUENCE_SPACE // 2


def sequence_of(data: bytes) -> int:
    """The sequence number of a packet we built (D-RSP-10)."""
    return int.from_bytes(data[SEQUENCE_AT : SEQUENCE_AT + 2])


def summary(model: RobotModel, header: Header, body: Body | None) -> str:
    """One line of a packet, for the transcript."""
    kind = header.type
    name = kind.name if isinstance(kind, PacketType) else f"type {kind}"
    head = f"{name} #{header.sequence}"
    if kind is PacketType.HELLO and isinstance(body, Hello):
        return (
            f"{head} model={header.model_id} enc={int(header.encryption)}"
            f" nonce={body.client_nonce[:4].hex()}.. period={body.period_ms}ms"
            + (f" mac={body.mac[:4].hex()}.." if body.mac else "")
        )
    if kind is PacketType.REFUSED and isinstance(body, Refused):
        return (
            f"{head} model={header.model_id} enc={int(header.encryption)} {body.reason.name}"
            f" last={header.last_received}"
        )
    text = (
        f"{head} t={header.timestamp} sid={header.session_id:x} last={header.last_received}"
        f" buf={header.buffer:#x}"
    )
    if header.model_id != model.model_id or header.encryption:
        text += f" model={header.model_id} enc={int(header.encryption)}"
    if body is None:
        return text + " (sealed)"
    if isinstance(body, Welcome):
        return text + f" nonce={body.robot_nonce[:4].hex()}.. period={body.period_ms}ms"
    if isinstance(body, Bye | Refused):
        return text + f" {body.reason.name}"
    if isinstance(body, Period):
        return text + f" period={body.period_ms}ms"
    if isinstance(body, MapBody):
        return text + " [" + ", ".join(_item(model, item) for item in body.items) + "]"
    return text


def _item(model: RobotModel, item: Item) -> str:
    text = model.devices[item.device].name
    if item.id is not None:
        text += f"#{item.id}"
    if item.values is not None:
        shown = ",".join(f"{k}={_value(v)}" for k, v in item.values.items())
        text += "{" + shown + "}"
    return text


def _value(value: Value) -> str:
    if isinstance(value, bytes):
        return f"<{len(value)} bytes>"
    if isinstance(value, float):
        return f"{value:.3g}"
    if isinstance(value, tuple):
        return "(" + ",".join(_value(v) for v in value) + ")"
    return str(value)
