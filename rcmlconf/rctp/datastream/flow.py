"""FLOW payload bodies (D-RCTP-22): requests, ACKs and NACKs of the data stream's flow control.

A body is a 4-byte preamble — message (request, ACK, NACK), operation, 16-bit request id — and
then the fields of that message and operation, each kind with a fixed length. One frozen dataclass
per kind; `pull_flow`/`push_flow` find a kind's layout by `(message, operation)` in a table.

Two kinds carry their operation as a field rather than by class, because the operation may be one
this side does not know: `Nack` (NACK 1 "unknown operation" echoes it) and `UnknownRequest` (the
request NACK 1 answers; its fields are kept as raw bytes, since their layout is unknown). An ACK of
an unknown operation answers nothing this side asked, and is malformed.

Times are 64-bit NTP timestamps held as ints (see `clock`); intervals and timeouts are 32-bit
microseconds.
"""

from __future__ import annotations

import dataclasses
import enum
import struct
from collections.abc import Callable
from dataclasses import dataclass
from typing import ClassVar

from rcmlconf.buffer import Buffer
from rcmlconf.errors import EncodeError, ProtocolError
from rcmlconf.wording import plural


class Message(enum.IntEnum):
    REQUEST = 0
    ACK = 1
    NACK = 2


class Operation(enum.IntEnum):
    HEARTBEAT = 1
    GET_INTERVAL = 2
    SET_INTERVAL = 3
    GET_TIMEOUT = 4
    SET_TIMEOUT = 5


class Direction(enum.IntEnum):
    """Always from the client's point of view (D-RCML-6): read is robot to client."""

    READ = 1
    WRITE = 2


class NackReason(enum.IntEnum):
    UNKNOWN_OPERATION = 1
    UNKNOWN_STREAM = 2
    VALUE_REFUSED = 3
    NOT_PERMITTED = 4
    MALFORMED = 5


# -- the kinds -------------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class HeartbeatRequest:
    message: ClassVar[Message] = Message.REQUEST
    operation: ClassVar[Operation] = Operation.HEARTBEAT
    request_id: int
    #: When the request was sent, by the requester's clock.
    t1: int


@dataclass(frozen=True, slots=True)
class HeartbeatAck:
    message: ClassVar[Message] = Message.ACK
    operation: ClassVar[Operation] = Operation.HEARTBEAT
    request_id: int
    #: The request's T1, echoed (R-RCTP-48).
    t1: int
    #: When the request arrived and when this ACK was sent, by the answerer's clock.
    t2: int
    t3: int


@dataclass(frozen=True, slots=True)
class IntervalGet:
    message: ClassVar[Message] = Message.REQUEST
    operation: ClassVar[Operation] = Operation.GET_INTERVAL
    request_id: int
    direction: Direction


@dataclass(frozen=True, slots=True)
class IntervalGetAck:
    message: ClassVar[Message] = Message.ACK
    operation: ClassVar[Operation] = Operation.GET_INTERVAL
    request_id: int
    direction: Direction
    interval: int


@dataclass(frozen=True, slots=True)
class IntervalSet:
    message: ClassVar[Message] = Message.REQUEST
    operation: ClassVar[Operation] = Operation.SET_INTERVAL
    request_id: int
    direction: Direction
    interval: int


@dataclass(frozen=True, slots=True)
class IntervalSetAck:
    message: ClassVar[Message] = Message.ACK
    operation: ClassVar[Operation] = Operation.SET_INTERVAL
    request_id: int
    direction: Direction
    #: The interval now in force, which need not be the one asked for.
    interval: int


@dataclass(frozen=True, slots=True)
class TimeoutGet:
    message: ClassVar[Message] = Message.REQUEST
    operation: ClassVar[Operation] = Operation.GET_TIMEOUT
    request_id: int
    direction: Direction


@dataclass(frozen=True, slots=True)
class TimeoutGetAck:
    message: ClassVar[Message] = Message.ACK
    operation: ClassVar[Operation] = Operation.GET_TIMEOUT
    request_id: int
    direction: Direction
    timeout: int


@dataclass(frozen=True, slots=True)
class TimeoutSet:
    message: ClassVar[Message] = Message.REQUEST
    operation: ClassVar[Operation] = Operation.SET_TIMEOUT
    request_id: int
    direction: Direction
    timeout: int


@dataclass(frozen=True, slots=True)
class TimeoutSetAck:
    message: ClassVar[Message] = Message.ACK
    operation: ClassVar[Operation] = Operation.SET_TIMEOUT
    request_id: int
    direction: Direction
    #: The timeout now in force.
    timeout: int


@dataclass(frozen=True, slots=True)
class Nack:
    message: ClassVar[Message] = Message.NACK
    request_id: int
    #: The refused request's operation, echoed: any byte, since NACK 1 answers unknown ones.
    operation: int
    reason: NackReason


@dataclass(frozen=True, slots=True)
class UnknownRequest:
    """A request for an operation this side does not know: it can still be answered NACK 1."""

    message: ClassVar[Message] = Message.REQUEST
    request_id: int
    operation: int
    fields: bytes


#: The kinds whose class fixes the operation.
FixedKind = (
    HeartbeatRequest
    | HeartbeatAck
    | IntervalGet
    | IntervalGetAck
    | IntervalSet
    | IntervalSetAck
    | TimeoutGet
    | TimeoutGetAck
    | TimeoutSet
    | TimeoutSetAck
)
FlowMessage = FixedKind | Nack | UnknownRequest

# -- the codec -------------------------------------------------------------------------------------

PREAMBLE = struct.Struct(">BBH")

_Pull = Callable[[Buffer, int, int, int], FlowMessage]
_Push = Callable[[Buffer, FlowMessage], None]

#: Fields whose bytes must be a member of an enum: decoding checks them, encoding refuses others.
_ENUMS: dict[str, type[enum.IntEnum]] = {"direction": Direction, "reason": NackReason}


def _choices(members: type[enum.IntEnum]) -> str:
    """'1 read, 2 write': what a dissector shows beside a byte that is none of them."""
    return ", ".join(f"{m.value} {m.name.lower().replace('_', ' ')}" for m in members)


def _fixed_codec(cls: type[FlowMessage], codes: str) -> tuple[_Pull, _Push]:
    """A kind whose fields after the preamble have one layout: `codes`, in field order."""
    fmt = struct.Struct(">" + codes)
    names = [f.name for f in dataclasses.fields(cls) if f.name not in ("request_id", "operation")]
    # The operation is a field only of the kinds that echo any operation (Nack).
    carries_operation = "operation" in {f.name for f in dataclasses.fields(cls)}
    assert len(names) == len(codes), (cls, names, codes)  # one code per field
    checked = [
        (index, _ENUMS[name], struct.calcsize(">" + codes[:index]))
        for index, name in enumerate(names)
        if name in _ENUMS
    ]

    def pull(buf: Buffer, operation: int, request_id: int, length: int) -> FlowMessage:
        start = buf.position
        if length != fmt.size:
            # Too short: the fields do not fit from their start; too long: the first extra byte.
            where = start if length < fmt.size else start + fmt.size
            raise ProtocolError(
                f"{cls.__name__} has {plural(length, 'byte')} of fields, not {fmt.size}", where
            )
        values = list(buf.pull_struct(fmt))
        for index, members, offset in checked:
            try:
                values[index] = members(values[index])
            except ValueError:
                raise ProtocolError(
                    f"{names[index]} {values[index]} is none of {_choices(members)}",
                    start + offset,
                ) from None
        if carries_operation:
            values.insert(0, operation)
        return cls(request_id, *values)

    def push(buf: Buffer, flow: FlowMessage) -> None:
        values = [getattr(flow, name) for name in names]
        for index, members, _ in checked:
            if values[index] not in members.__members__.values():
                raise EncodeError(f"{names[index]} {values[index]!r} is not a {members.__name__}")
        try:
            buf.push_struct(fmt, *values)
        except struct.error as exc:
            raise EncodeError(f"{flow!r} does not fit its fields: {exc}") from None

    return pull, push


def _pull_unknown(buf: Buffer, operation: int, request_id: int, length: int) -> FlowMessage:
    return UnknownRequest(request_id, operation, buf.pull_bytes(length))


def _push_unknown(buf: Buffer, flow: FlowMessage) -> None:
    assert isinstance(flow, UnknownRequest)  # the table sends only these here
    if flow.operation in Operation.__members__.values():
        raise EncodeError(f"operation {flow.operation} is known: use its own class")
    buf.push_bytes(flow.fields)


#: D-RCTP-22: the layout of each fixed kind's fields after the preamble, in field order.
_FIXED: dict[type[FixedKind], str] = {
    HeartbeatRequest: "Q",
    HeartbeatAck: "QQQ",
    IntervalGet: "B",
    IntervalGetAck: "BI",
    IntervalSet: "BI",
    IntervalSetAck: "BI",
    TimeoutGet: "B",
    TimeoutGetAck: "BI",
    TimeoutSet: "BI",
    TimeoutSetAck: "BI",
}
_CODECS: dict[type[FlowMessage], tuple[_Pull, _Push]] = {
    **{cls: _fixed_codec(cls, codes) for cls, codes in _FIXED.items()},
    Nack: _fixed_codec(Nack, "B"),
    UnknownRequest: (_pull_unknown, _push_unknown),
}
#: (message, operation) -> kind, for the fixed kinds.
_KINDS: dict[tuple[int, int], type[FlowMessage]] = {
    (cls.message, cls.operation): cls for cls in _FIXED
}
#: message -> kind, for an operation no fixed kind of that message has.
_ANY_OPERATION: dict[int, type[FlowMessage]] = {Message.REQUEST: UnknownRequest, Message.NACK: Nack}


def pull_flow(buf: Buffer, length: int) -> FlowMessage:
    """The FLOW body of `length` bytes at the buffer's position; it must be exactly one message."""
    start = buf.position
    if length < PREAMBLE.size:
        raise ProtocolError(
            f"FLOW body of {plural(length, 'byte')}, shorter than its preamble", start
        )
    message, operation, request_id = buf.pull_struct(PREAMBLE)
    kind = _KINDS.get((message, operation)) or _ANY_OPERATION.get(message)
    if kind is None:
        if message not in Message.__members__.values():
            raise ProtocolError(f"FLOW message {message} is none of {_choices(Message)}", start)
        raise ProtocolError(
            f"{Message(message).name} of operation {operation}, none of {_choices(Operation)}",
            start + 1,
        )
    return _CODECS[kind][0](buf, operation, request_id, length - PREAMBLE.size)


def push_flow(buf: Buffer, flow: FlowMessage) -> None:
    codec = _CODECS.get(type(flow))
    if codec is None:
        raise EncodeError(f"{type(flow).__name__} is not a FLOW message")
    try:
        buf.push_struct(PREAMBLE, flow.message, flow.operation, flow.request_id)
    except struct.error as exc:
        raise EncodeError(f"{flow!r} does not fit the FLOW preamble: {exc}") from None
    codec[1](buf, flow)


def encode_flow(flow: FlowMessage) -> bytes:
    buf = Buffer()
    push_flow(buf, flow)
    return buf.data()


def decode_flow(body: bytes) -> FlowMessage:
    """Exactly one FLOW body; offsets in errors count from its first byte."""
    return pull_flow(Buffer(body), len(body))
