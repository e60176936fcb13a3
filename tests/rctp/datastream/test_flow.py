"""FLOW payload bodies (D-RCTP-22): each kind's bytes, round trips, and what a receiver refuses.

The datagrams of vectors/rctp/ are checked in test_packets.py; `flow_messages` is shared with it.
"""

from __future__ import annotations

import struct

import pytest
from hypothesis import given
from hypothesis import strategies as st
from support.datastream import flow_messages

from rcmlconf.buffer import Buffer
from rcmlconf.errors import EncodeError, ProtocolError
from rcmlconf.rctp.datastream.flow import (
    Direction,
    FlowMessage,
    HeartbeatAck,
    HeartbeatRequest,
    IntervalGet,
    IntervalGetAck,
    IntervalSet,
    IntervalSetAck,
    Message,
    Nack,
    NackReason,
    Operation,
    TimeoutGet,
    TimeoutGetAck,
    TimeoutSet,
    TimeoutSetAck,
    UnknownRequest,
    decode_flow,
    encode_flow,
    pull_flow,
)

#: Every kind whose operation its class fixes, with the layout D-RCTP-22 gives its fields.
FIXED: dict[type[FlowMessage], str] = {
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


def test_ten_fixed_kinds_one_per_message_and_operation() -> None:
    keys = {(cls.message, cls.operation) for cls in FIXED}
    assert keys == {(m, op) for m in (Message.REQUEST, Message.ACK) for op in Operation}


@pytest.mark.parametrize("cls", list(FIXED), ids=lambda cls: cls.__name__)
def test_each_kind_is_its_preamble_then_its_fields(cls: type[FlowMessage]) -> None:
    codes = FIXED[cls]
    # 1 for every field: a valid direction, and a valid number for the rest.
    fields = [1] * len(codes)
    flow = cls(0x0102, *fields)
    expected = struct.pack(">BBH", cls.message, cls.operation, 0x0102)
    expected += struct.pack(">" + codes, *fields)
    assert encode_flow(flow) == expected
    assert decode_flow(expected) == flow


def test_heartbeat_ack_keeps_its_times_in_order() -> None:
    ack = HeartbeatAck(7, t1=1, t2=2, t3=3)
    assert encode_flow(ack)[4:] == struct.pack(">QQQ", 1, 2, 3)


def test_a_nack_echoes_an_operation_this_side_does_not_know() -> None:
    body = bytes([2, 9, 0, 5, NackReason.UNKNOWN_OPERATION])
    assert decode_flow(body) == Nack(5, 9, NackReason.UNKNOWN_OPERATION)


def test_a_request_of_an_unknown_operation_can_be_answered() -> None:
    request = decode_flow(bytes([0, 42, 0x12, 0x34, 0xAB]))
    assert request == UnknownRequest(0x1234, 42, b"\xab")
    answer = Nack(request.request_id, request.operation, NackReason.UNKNOWN_OPERATION)
    assert encode_flow(answer) == bytes([2, 42, 0x12, 0x34, 1])


@given(flow_messages)
def test_round_trip(flow: FlowMessage) -> None:
    assert decode_flow(encode_flow(flow)) == flow


@given(flow_messages)
def test_a_body_is_read_in_place_in_a_larger_buffer(flow: FlowMessage) -> None:
    body = encode_flow(flow)
    buf = Buffer(b"\xee" * 3 + body + b"\xff")
    buf.pull_bytes(3)
    assert pull_flow(buf, len(body)) == flow
    assert buf.remaining == 1


@given(st.binary(max_size=40))
def test_any_bytes_give_a_message_or_a_protocol_error(data: bytes) -> None:
    try:
        flow = decode_flow(data)
    except ProtocolError as error:
        offset = error.offset
    else:
        assert encode_flow(flow) == data  # one encoding per message
        return
    assert 0 <= offset <= len(data)


@given(flow_messages.filter(lambda flow: not isinstance(flow, UnknownRequest)), st.data())
def test_a_fixed_body_of_another_length_is_refused(flow: FlowMessage, data: st.DataObject) -> None:
    body = encode_flow(flow)
    changed = data.draw(
        st.one_of(
            st.integers(0, len(body) - 1).map(lambda cut: body[:cut]),
            st.binary(min_size=1, max_size=8).map(lambda extra: body + extra),
        )
    )
    with pytest.raises(ProtocolError) as failure:
        decode_flow(changed)
    assert failure.value.offset <= len(changed)


@pytest.mark.parametrize(
    ("body", "offset"),
    [
        (bytes([3, 1, 0, 1]) + bytes(8), 0),  # message 3
        (bytes([1, 6, 0, 1]), 1),  # ACK of operation 6
        (bytes([1, 0, 0, 1]) + bytes(8), 1),  # ACK of operation 0
        (bytes([0, 2, 0, 1, 0]), 4),  # direction 0
        (bytes([1, 3, 0, 1, 3, 0, 0, 0, 1]), 4),  # direction 3
        (bytes([2, 1, 0, 1, 0]), 4),  # reason 0
        (bytes([2, 1, 0, 1, 6]), 4),  # reason 6
        (bytes([0, 1, 0]), 0),  # no room for the preamble
        (bytes([0, 1, 0, 1]) + bytes(7), 4),  # T1 one byte short: due where the fields start
        (bytes([0, 4, 0, 1, 1, 0]), 5),  # get timeout with a byte too many
    ],
)
def test_refused_where_the_fault_is(body: bytes, offset: int) -> None:
    with pytest.raises(ProtocolError) as failure:
        decode_flow(body)
    assert failure.value.offset == offset


@pytest.mark.parametrize(
    "flow",
    [
        HeartbeatRequest(1 << 16, 0),
        HeartbeatRequest(-1, 0),
        HeartbeatRequest(1, 1 << 64),
        HeartbeatAck(1, 0, 0, -1),
        IntervalGetAck(1, Direction.READ, 1 << 32),
        IntervalSet(1, 3, 10),  # direction 3
        TimeoutSet(1, Direction.WRITE, 1.5),  # not an int
        Nack(1, 256, NackReason.MALFORMED),
        Nack(1, 1, 9),  # a reason D-RCTP-22 does not have
        UnknownRequest(1, Operation.HEARTBEAT, b""),  # would come back a HeartbeatRequest
    ],
    ids=repr,
)
def test_what_cannot_be_sent_is_a_local_error(flow: FlowMessage) -> None:
    with pytest.raises(EncodeError):
        encode_flow(flow)


def test_only_flow_messages_are_encoded() -> None:
    with pytest.raises(EncodeError):
        encode_flow(object())


def test_kinds_with_the_same_fields_are_not_equal() -> None:
    assert IntervalGet(1, Direction.READ) != TimeoutGet(1, Direction.READ)
