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
from typing import ClassVar, NamedTuple

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


class DataPayload(NamedTuple):
    """D-RCTP-20: the values of one stream's data nodes, still encoded (`values` decodes them).

    Immutable like the other payloads, but a NamedTuple, as `Packet` is: one is made for every
    DATA a stream sends (D-RCTP-20), and a frozen dataclass costs four times as much to make.
    """

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


class Packet(NamedTuple):
    """One datagram. The version is not a field: only version 2 decodes, and 2 is what is sent.

    A NamedTuple, as `rsp.codec.header.Header` is, not a frozen dataclass: one is made for every
    datagram of the data stream (a stream's values each period, D-RCTP-20), and `rcmlconf
    dissect` makes a million of them for a large capture; a frozen dataclass costs four times as
    much to make (bench/dissect_speed.py).
    """

    #: Per sender per session, one more per packet modulo 65,536 (D-RCTP-19, R-RCTP-41).
    sequence: int
    #: The session's data-stream tag of SETUP's `Transport` (D-RCTP-18).
    tag: int
    #: When the sender sent it, by its own clock: 64-bit NTP (`clock`).
    timestamp: int
    payloads: tuple[Payload, ...]


# -- decoding --------------------------------------------------------------------------------------

#: The header and a first payload's header.
_ONE = struct.Struct(HEADER.format + PAYLOAD_HEADER.format[1:])
_unpack_header, _unpack_one = HEADER.unpack_from, _ONE.unpack_from
_unpack_payload_header = PAYLOAD_HEADER.unpack_from
_HEADER_SIZE, _PAYLOAD_HEADER_SIZE, _ONE_SIZE = HEADER.size, PAYLOAD_HEADER.size, _ONE.size
_DATA, _FLOW = int(PayloadType.DATA), int(PayloadType.FLOW)
#: `Packet(...)` and `DataPayload(...)` without the call to their `__new__`: the fields are the
#: decoder's own, in their order.
_new = tuple.__new__


def _flow_payload(stream: int, body: bytes, start: int) -> Payload:
    try:
        return FlowPayload(stream, decode_flow(body))
    except ProtocolError as error:  # R-RCTP-53: the packet stays readable
        return MalformedFlowPayload(stream, body, error.reason, start + error.offset)


def pull_packet(data: bytes | bytearray | memoryview) -> Packet:
    """The packet of one whole datagram (R-RCTP-39)."""
    size = len(data)
    if _ONE_SIZE <= size <= MAX_DATAGRAM and type(data) is bytes:
        version, count, sequence, tag, timestamp, kind, stream, length = _unpack_one(data)
        if version == VERSION and count == 1 and kind == _DATA and length == size - _ONE_SIZE:
            # What nearly every datagram is (a stream's values each period, D-RCTP-20): one DATA
            # payload that fills it, checked as the loop below checks it, made in a third of the
            # time. Anything else, and every error, is the loop's.
            payload = _new(DataPayload, (stream, data[_ONE_SIZE:]))
            return _new(Packet, (sequence, tag, timestamp, (payload,)))
    if size > MAX_DATAGRAM:
        raise ProtocolError(f"datagram of {size} bytes, more than {MAX_DATAGRAM}", MAX_DATAGRAM)
    # The version first: a datagram of another version has another layout, so it is reported as
    # that rather than as whatever its bytes would break of this one.
    if size and data[0] != VERSION:
        raise ProtocolError(f"version {data[0]}, not {VERSION}", 0, _RULE)
    if size < _HEADER_SIZE:
        raise ProtocolError(f"header of {size} bytes, not {_HEADER_SIZE}", size, _RULE)
    if type(data) is not bytes:
        data = bytes(data)  # bodies are bytes, whatever the datagram came as
    _, count, sequence, tag, timestamp = _unpack_header(data)
    if count == 0:
        raise ProtocolError("payload count 0: a packet holds 1 to 255 payloads", 1, _RULE)
    payloads: list[Payload] = []
    position = _HEADER_SIZE
    for index in range(count):
        start = position
        left = size - start - _PAYLOAD_HEADER_SIZE
        if left < 0:
            raise ProtocolError(
                f"payload {index + 1} of {count} has {size - start} of {_PAYLOAD_HEADER_SIZE}"
                " header bytes",
                start,
                _RULE,
            )
        kind, stream, length = _unpack_payload_header(data, start)
        if length > left:
            raise ProtocolError(
                f"payload {index + 1} of {count}: body length {length} runs past the end"
                f" ({plural(left, 'byte')} left)",
                start + 2,
                _RULE,
            )
        body_start = start + _PAYLOAD_HEADER_SIZE
        position = body_start + length
        body = data[body_start:position]
        if kind == _DATA:
            payloads.append(_new(DataPayload, (stream, body)))
        elif kind == _FLOW:
            payloads.append(_flow_payload(stream, body, body_start))
        else:
            payloads.append(UnknownPayload(kind, stream, body))  # R-RCTP-51
    if position != size:
        raise ProtocolError(
            f"{plural(size - position, 'byte')} after the last of {plural(count, 'payload')}",
            position,
            _RULE,
        )
    return _new(Packet, (sequence, tag, timestamp, tuple(payloads)))


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
