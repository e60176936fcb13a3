"""The played server's mutated answers to a client's heartbeat (D-FUZZ-8): an ACK of the
request's id whose times break R-RCTP-48, read back with the core's own FLOW codec."""

from __future__ import annotations

import random

from hypothesis import given
from hypothesis import strategies as st

from rcmlconf.fuzz.mutate import HEARTBEAT_ACK, heartbeat_echo, heartbeat_times
from rcmlconf.rctp.datastream.flow import HeartbeatAck, decode_flow, encode_flow

VALID = encode_flow(HeartbeatAck(7, 11, 13, 17))


@given(st.integers(0, 2**32))
def test_the_times_stay_an_ack_of_the_same_request(seed: int) -> None:
    ack = decode_flow(heartbeat_times(VALID, random.Random(seed)))
    assert isinstance(ack, HeartbeatAck)
    assert (ack.request_id, ack.t1) == (7, 11)
    assert (ack.t2, ack.t3) != (13, 17)


def test_often_the_answer_left_before_the_request_arrived() -> None:
    acks = [decode_flow(heartbeat_times(VALID, random.Random(seed))) for seed in range(200)]
    before = [ack for ack in acks if isinstance(ack, HeartbeatAck) and ack.t3 < ack.t2]
    assert len(before) >= 70  # half by design, and some edges fall that way too


@given(st.integers(0, 2**32))
def test_the_echo_flips_some_bit_of_t1_and_nothing_else(seed: int) -> None:
    ack = decode_flow(heartbeat_echo(VALID, random.Random(seed)))
    assert isinstance(ack, HeartbeatAck)
    assert ack.t1 != 0  # the bits to flip in the request's T1: never none
    assert (ack.request_id, ack.t2, ack.t3) == (7, 13, 17)


def test_both_kinds_are_offered() -> None:
    assert set(HEARTBEAT_ACK) == {"heartbeat-times", "heartbeat-echo"}
