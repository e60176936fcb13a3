"""The bodies of the packet types (D-RSP-11), and the session bodies' layouts.

HELLO, WELCOME, REFUSED, BYE and PERIOD have fixed layouts, given here as data: each body class
lists its parts, and one pair of functions reads and writes any of them. HELLO and WELCOME end with
a MAC in an encrypted session and have none otherwise (D-RSP-21), so their layout depends on the
header. DOWNLINK, UPLINK and ACK carry a Device Map and payloads (`MapBody`, read by `plans`).

The session bodies are frozen dataclasses. `Item` and `Packet`, made for every packet, are
NamedTuples for the reason `header` gives.
"""

from __future__ import annotations

import enum
import struct
from collections.abc import Callable, Mapping
from dataclasses import dataclass, fields
from typing import Any, ClassVar, NamedTuple

from rcmlconf.buffer import Buffer
from rcmlconf.errors import EncodeError, ProtocolError
from rcmlconf.rsp.codec.header import Encryption, Header, PacketType
from rcmlconf.rsp.layout import MAC_SIZE, NONCE_SIZE
from rcmlconf.values import Value

#: R-RSP-16: a body is exactly what its type needs.
RULE = "R-RSP-16"
#: D-RSP-13: the period T, in milliseconds.
MIN_PERIOD_MS = 5
MAX_PERIOD_MS = 10000


class RefusedReason(enum.IntEnum):
    """REFUSED's reason (D-RSP-11)."""

    UNKNOWN_MODEL = 1
    ENCRYPTION_NOT_OFFERED = 2
    BUSY = 3
    NOT_AUTHENTICATED = 4


class ByeReason(enum.IntEnum):
    """BYE's reason (D-RSP-11)."""

    CLOSED = 0
    TIMEOUT = 1
    SHUTDOWN = 2


# -- the parts of a fixed layout ---------------------------------------------------------------


class _Part(NamedTuple):
    """One field of a fixed layout: its bytes, what it may hold, and the value a wire value is."""

    struct: struct.Struct
    #: Why a value is not one this part holds (sent or received), or None.
    fault: Callable[[Any], str | None]
    make: Callable[[Any], Any] = bytes


def _octets(size: int, what: str) -> _Part:
    def fault(value: Any) -> str | None:
        if isinstance(value, bytes) and len(value) == size:
            return None
        return f"{what} must be {size} bytes, not {value!r}"

    return _Part(struct.Struct(f">{size}s"), fault)


def _period(value: Any) -> str | None:
    if (
        isinstance(value, int)
        and not isinstance(value, bool)
        and MIN_PERIOD_MS <= value <= MAX_PERIOD_MS
    ):
        return None
    return f"period {value!r} ms is outside {MIN_PERIOD_MS} to {MAX_PERIOD_MS} (D-RSP-13)"


def _reason(reasons: type[enum.IntEnum]) -> _Part:
    known = {int(member) for member in reasons}

    def fault(value: Any) -> str | None:
        if isinstance(value, int) and not isinstance(value, bool) and value in known:
            return None
        return f"{reasons.__name__} {value!r} is none of {sorted(known)}"

    return _Part(struct.Struct(">B"), fault, reasons)


_NONCE = _octets(NONCE_SIZE, "a nonce")
_PERIOD = _Part(struct.Struct(">H"), _period, int)
_MAC = _octets(MAC_SIZE, "a MAC")


# -- the bodies --------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class Hello:
    """The local system opens a session (D-RSP-12)."""

    parts: ClassVar[tuple[_Part, ...]] = (_NONCE, _PERIOD)
    signed: ClassVar[bool] = True
    client_nonce: bytes
    #: The period the local system wants, in milliseconds.
    period_ms: int
    #: 16 bytes in an encrypted session, b"" otherwise (D-RSP-21).
    mac: bytes = b""


@dataclass(frozen=True, slots=True)
class Welcome:
    """The robot opens the session the header's session ID names (D-RSP-12)."""

    parts: ClassVar[tuple[_Part, ...]] = (_NONCE, _NONCE, _PERIOD)
    signed: ClassVar[bool] = True
    #: HELLO's, echoed.
    client_nonce: bytes
    robot_nonce: bytes
    #: The period in force, which may be longer than HELLO's (D-RSP-13).
    period_ms: int
    mac: bytes = b""


@dataclass(frozen=True, slots=True)
class Refused:
    parts: ClassVar[tuple[_Part, ...]] = (_reason(RefusedReason),)
    signed: ClassVar[bool] = False
    reason: RefusedReason


@dataclass(frozen=True, slots=True)
class Bye:
    parts: ClassVar[tuple[_Part, ...]] = (_reason(ByeReason),)
    signed: ClassVar[bool] = False
    reason: ByeReason


@dataclass(frozen=True, slots=True)
class Period:
    """T changed while the session runs (D-RSP-13)."""

    parts: ClassVar[tuple[_Part, ...]] = (_PERIOD,)
    signed: ClassVar[bool] = False
    period_ms: int


class Item(NamedTuple):
    """What one set bit of a Device Map brings (D-RSP-14): `device` is its position in model
    order; `id` an occurrence's or an acknowledged occurrence's ID, else None; `values` the fields
    of a state or occurrence, else None (`layout.Bit` says which).
    """

    device: int
    id: int | None = None
    values: Mapping[str, Value] | None = None


@dataclass(frozen=True, slots=True)
class MapBody:
    """DOWNLINK, UPLINK and ACK: one item per set bit, in model order (D-RSP-14)."""

    items: tuple[Item, ...]


_new_body = object.__new__
_set_items = MapBody.__dict__["items"].__set__


def map_body(items: tuple[Item, ...]) -> MapBody:
    """`MapBody(items)`, made as its `__init__` makes it but without the call: one is made for
    every map packet read."""
    body = _new_body(MapBody)
    _set_items(body, items)
    return body


SessionBody = Hello | Welcome | Refused | Bye | Period
Body = SessionBody | MapBody


class Packet(NamedTuple):
    """A plaintext packet: what an unencrypted session sends, and what an encrypted one seals."""

    header: Header
    body: Body


#: The body each packet type has (D-RSP-11).
BODIES: dict[PacketType, type[Body]] = {
    PacketType.HELLO: Hello,
    PacketType.WELCOME: Welcome,
    PacketType.REFUSED: Refused,
    PacketType.DOWNLINK: MapBody,
    PacketType.UPLINK: MapBody,
    PacketType.ACK: MapBody,
    PacketType.BYE: Bye,
    PacketType.PERIOD: Period,
}


def _layout(cls: type[SessionBody], header: Header) -> tuple[_Part, ...]:
    """D-RSP-21: HELLO and WELCOME carry a MAC only in encrypted sessions."""
    signed = cls.signed and header.encryption != Encryption.NONE
    return (*cls.parts, _MAC) if signed else cls.parts


def pull_session_body(cls: type[SessionBody], header: Header, buf: Buffer) -> SessionBody:
    """A session body from the whole of `buf`; offsets in errors are the buffer's."""
    values = []
    for part in _layout(cls, header):
        start = buf.position
        try:
            (raw,) = buf.pull_struct(part.struct)
        except ProtocolError as exc:
            raise ProtocolError(
                f"{cls.__name__} body cut short: {exc.reason}", start, RULE
            ) from None
        fault = part.fault(raw)
        if fault is not None:
            raise ProtocolError(fault, start, RULE)
        values.append(part.make(raw))
    if not buf.eof():
        raise ProtocolError(
            f"{buf.remaining} bytes after the {cls.__name__} body", buf.position, RULE
        )
    return cls(*values)


def push_session_body(header: Header, body: SessionBody) -> bytes:
    parts = _layout(type(body), header)
    values = [getattr(body, field.name) for field in fields(body)]
    # An unsigned layout has no MAC part: the body's `mac` must then be empty.
    if len(parts) < len(values) and values.pop() != b"":
        raise EncodeError(f"{type(body).__name__} carries no MAC in a session without encryption")
    encoded = []
    for part, value in zip(parts, values, strict=True):
        fault = part.fault(value)
        if fault is not None:
            raise EncodeError(f"{type(body).__name__}: {fault}")
        encoded.append(part.struct.pack(value))
    return b"".join(encoded)
