"""Data-stream packets (D-RCTP-19): a 16-byte header, then payloads that fill the datagram.

`pull_packet` takes a whole datagram and lets only `ProtocolError` escape, with the offset from
the datagram's first byte; `push_packet` raises `EncodeError` for a packet that cannot be sent.
The encoding is canonical — every field has one width and one place — so a datagram that decodes
re-encodes to the same bytes.

A DATA body stays bytes here: decoding it needs the stream's RCML access (`values`). A FLOW body
is decoded (`flow`); one that breaks its layout is kept as `MalformedFlowPayload` and does not make
the packet unreadable (D-RCTP-22, R-RCTP-53): only broken framing does. A payload of another type
is kept as `UnknownPayload`, so that a dissector can show it and a receiver can skip it by its
length (R-RCTP-51).
"""

from __future__ import annotations

import enum
import struct
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import ClassVar

from rcmlconf.buffer import Buffer
from rcmlconf.errors import EncodeError, ProtocolError
from rcmlconf.rctp.datastream.flow import (
    PREAMBLE,
    FlowMessage,
    Message,
    NackReason,
    decode_flow,
    encode_flow,
)
from rcmlconf.wording import plural

_RULE = "R-RCTP-39"

VERSION = 2
#: version, payload count, sequence number, session tag, NTP timestamp.
HEADER = struct.Struct(">BBHIQ")
#: payload type, stream id, body length.
PAYLOAD_HEADER = struct.Struct(">BBH")
#: D-RCTP-19: 1 to 255 payloads, as the count's byte allows.
MAX_PAYLOADS = 255
#: The largest UDP payload over IPv4 (65,535 - 20 bytes of IP header - 8 of UDP header). The spec
#: sets no limit; this is the one every path can carry, and a receiver reads nothing past it.
MAX_DATAGRAM = 65507


class PayloadType(enum.IntEnum):
    DATA = 1
    FLOW = 2


@dataclass(frozen=True, slots=True)
class DataPayload:
    """D-RCTP-20: the values of one stream's data nodes, still encoded (`values` decodes them)."""

    stream: int
    body: bytes


@dataclass(frozen=True, slots=True)
class FlowPayload:
    """D-RCTP-22: flow control; `stream` is 0 for the session (a heartbeat) or the stream's id."""

    stream: int
    flow: FlowMessage


@dataclass(frozen=True, slots=True)
class MalformedFlowPayload:
    """A FLOW body that breaks its layout (R-RCTP-52) in a packet whose framing holds.

    The packet's other payloads are read as usual; `answer` says whether a receiver owes a NACK
    (R-RCTP-53): only a request whose 4-byte preamble can be read gets one.
    """

    stream: int
    body: bytes
    reason: str
    #: Where the body breaks its layout, from the datagram's first byte.
    offset: int
    rule: ClassVar[str] = "R-RCTP-52"

    @property
    def answer(self) -> NackReason | None:
        if len(self.body) < PREAMBLE.size or self.body[0] != Message.REQUEST:
            return None
        return NackReason.MALFORMED

    @property
    def request_id(self) -> int | None:
        """The id a NACK echoes, when the body is a request whose preamble can be read."""
        return int(PREAMBLE.unpack_from(self.body)[2]) if self.answer else None

    @property
    def operation(self) -> int | None:
        return self.body[1] if self.answer else None


@dataclass(frozen=True, slots=True)
class UnknownPayload:
    """A payload type this side does not know (R-RCTP-51): skipped by its length, kept as bytes."""

    type: int
    stream: int
    body: bytes


Payload = DataPayload | FlowPayload | MalformedFlowPayload | UnknownPayload


@dataclass(frozen=True, slots=True)
class Packet:
    """One datagram. The version is not a field: only version 2 decodes, and 2 is what is sent."""

    #: Per sender per session, one more per packet modulo 65,536 (D-RCTP-19, R-RCTP-41).
    sequence: int
    #: The session's data-stream tag of SETUP's `Transport` (D-RCTP-18).
    tag: int
    #: When the sender sent it, by its own clock: 64-bit NTP (`clock`).
    timestamp: int
    payloads: tuple[Payload, ...]


# -- decoding --------------------------------------------------------------------------------------

#: (buffer, payload type, stream id, body length) -> the payload, its body read.
_PullBody = Callable[[Buffer, int, int, int], Payload]


def _pull_data(buf: Buffer, kind: int, stream: int, length: int) -> Payload:
    return DataPayload(stream, buf.pull_bytes(length))


def _pull_flow(buf: Buffer, kind: int, stream: int, length: int) -> Payload:
    start = buf.position
    body = buf.pull_bytes(length)
    try:
        return FlowPayload(stream, decode_flow(body))
    except ProtocolError as error:  # R-RCTP-53: the packet stays readable
        return MalformedFlowPayload(stream, body, error.reason, start + error.offset)


def _pull_unknown(buf: Buffer, kind: int, stream: int, length: int) -> Payload:
    return UnknownPayload(kind, stream, buf.pull_bytes(length))  # R-RCTP-51


_PULL_BODY: dict[int, _PullBody] = {PayloadType.DATA: _pull_data, PayloadType.FLOW: _pull_flow}


def pull_packet(data: bytes | bytearray | memoryview) -> Packet:
    """The packet of one whole datagram (R-RCTP-39)."""
    size = len(data)
    if size > MAX_DATAGRAM:
        raise ProtocolError(f"datagram of {size} bytes, more than {MAX_DATAGRAM}", MAX_DATAGRAM)
    # The version first: a datagram of another version has another layout, so it is reported as
    # that rather than as whatever its bytes would break of this one.
    if size and data[0] != VERSION:
        raise ProtocolError(f"version {data[0]}, not {VERSION}", 0, _RULE)
    if size < HEADER.size:
        raise ProtocolError(f"header of {size} bytes, not {HEADER.size}", size, _RULE)
    buf = Buffer(data)
    _, count, sequence, tag, timestamp = buf.pull_struct(HEADER)
    if count == 0:
        raise ProtocolError("payload count 0: a packet holds 1 to 255 payloads", 1, _RULE)
    payloads: list[Payload] = []
    for index in range(count):
        start = buf.position
        left = size - start - PAYLOAD_HEADER.size
        if left < 0:
            raise ProtocolError(
                f"payload {index + 1} of {count} has {size - start} of {PAYLOAD_HEADER.size}"
                " header bytes",
                start,
                _RULE,
            )
        kind, stream, length = buf.pull_struct(PAYLOAD_HEADER)
        if length > left:
            raise ProtocolError(
                f"payload {index + 1} of {count}: body length {length} runs past the end"
                f" ({plural(left, 'byte')} left)",
                start + 2,
                _RULE,
            )
        end = start + PAYLOAD_HEADER.size + length
        payloads.append(_PULL_BODY.get(kind, _pull_unknown)(buf, kind, stream, length))
        assert buf.position == end  # each body codec reads exactly `length` bytes, or raises
    if not buf.eof():
        raise ProtocolError(
            f"{plural(buf.remaining, 'byte')} after the last of {plural(count, 'payload')}",
            buf.position,
            _RULE,
        )
    return Packet(sequence, tag, timestamp, tuple(payloads))


# -- encoding --------------------------------------------------------------------------------------


def _data_body(payload: Payload) -> tuple[int, bytes]:
    assert isinstance(payload, DataPayload)  # the table sends only these here
    return PayloadType.DATA, bytes(payload.body)


def _flow_body(payload: Payload) -> tuple[int, bytes]:
    assert isinstance(payload, FlowPayload)
    return PayloadType.FLOW, encode_flow(payload.flow)


def _malformed_flow_body(payload: Payload) -> tuple[int, bytes]:
    assert isinstance(payload, MalformedFlowPayload)
    try:
        decode_flow(payload.body)
    except ProtocolError:
        return PayloadType.FLOW, bytes(payload.body)
    # It would come back as a FlowPayload: the round trip would not hold.
    raise EncodeError("this FLOW body is well formed: send it as a FlowPayload")


def _unknown_body(payload: Payload) -> tuple[int, bytes]:
    assert isinstance(payload, UnknownPayload)
    if payload.type in PayloadType.__members__.values():
        # It would come back as a DATA or FLOW payload: the round trip would not hold.
        raise EncodeError(f"payload type {payload.type} is known: use its own class")
    return payload.type, bytes(payload.body)


#: Payload class -> (type, body bytes).
_BODY: dict[type[Payload], Callable[[Payload], tuple[int, bytes]]] = {
    DataPayload: _data_body,
    FlowPayload: _flow_body,
    MalformedFlowPayload: _malformed_flow_body,
    UnknownPayload: _unknown_body,
}


def _body(payload: Payload) -> tuple[int, bytes]:
    body_of = _BODY.get(type(payload))
    if body_of is None:
        raise EncodeError(f"{type(payload).__name__} is not a payload")
    return body_of(payload)


def push_packet(packet: Packet) -> bytes:
    encoded = [(*_body(payload), payload.stream) for payload in packet.payloads]
    return push_datagram(packet.sequence, packet.tag, packet.timestamp, encoded)


#: A payload already encoded: (payload type, body, stream id).
EncodedPayload = tuple[int, bytes, int]


def push_datagram(
    sequence: int, tag: int, timestamp: int, payloads: Sequence[EncodedPayload]
) -> bytes:
    """A packet's bytes from its header fields and its payloads already encoded: what a sender
    on the beat uses, without making a `Packet` of every datagram (`push_packet` makes one)."""
    count = len(payloads)
    if not 1 <= count <= MAX_PAYLOADS:
        raise EncodeError(f"{count} payloads: a packet holds 1 to {MAX_PAYLOADS}")
    try:
        parts = [HEADER.pack(VERSION, count, sequence, tag, timestamp)]
        for kind, body, stream in payloads:
            parts.append(PAYLOAD_HEADER.pack(kind, stream, len(body)))
            parts.append(body)
    except struct.error as exc:
        raise EncodeError(f"a header field does not fit: {exc}") from None
    data = b"".join(parts)
    if len(data) > MAX_DATAGRAM:
        raise EncodeError(f"datagram of {len(data)} bytes, more than {MAX_DATAGRAM}")
    return data


def body_offsets(packet: Packet) -> tuple[int, ...]:
    """Where each payload's body starts in the packet's datagram: to place errors in a body (a
    DATA body's values, `values.stream_codec(...).decode`) in the datagram, for a dissector.
    """
    offsets = []
    position = HEADER.size
    for payload in packet.payloads:
        position += PAYLOAD_HEADER.size
        offsets.append(position)
        position += len(_body(payload)[1])
    return tuple(offsets)


def peek_tag(data: bytes) -> int | None:
    """A datagram's session tag, read before anything else, so that a server with one port for
    every session knows whose it is (D-RCTP-28); None when it cannot be a packet at all."""
    if len(data) < HEADER.size or data[0] != VERSION:
        return None
    return int.from_bytes(data[4:8], "big")
