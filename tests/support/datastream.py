"""Hypothesis strategies for the RCTP data stream, shared by its tests."""

from __future__ import annotations

from hypothesis import strategies as st

from rcmlconf.rctp.datastream.flow import (
    Direction,
    FlowMessage,
    HeartbeatAck,
    HeartbeatRequest,
    IntervalGet,
    IntervalGetAck,
    IntervalSet,
    IntervalSetAck,
    Nack,
    NackReason,
    Operation,
    TimeoutGet,
    TimeoutGetAck,
    TimeoutSet,
    TimeoutSetAck,
    UnknownRequest,
)

ids = st.integers(0, 0xFFFF)
times = st.integers(0, (1 << 64) - 1)
micros = st.integers(0, (1 << 32) - 1)
directions = st.sampled_from(Direction)
unknown_operations = st.integers(0, 255).filter(lambda op: op not in set(Operation))

flow_messages: st.SearchStrategy[FlowMessage] = st.one_of(
    st.builds(HeartbeatRequest, ids, times),
    st.builds(HeartbeatAck, ids, times, times, times),
    st.builds(IntervalGet, ids, directions),
    st.builds(IntervalGetAck, ids, directions, micros),
    st.builds(IntervalSet, ids, directions, micros),
    st.builds(IntervalSetAck, ids, directions, micros),
    st.builds(TimeoutGet, ids, directions),
    st.builds(TimeoutGetAck, ids, directions, micros),
    st.builds(TimeoutSet, ids, directions, micros),
    st.builds(TimeoutSetAck, ids, directions, micros),
    st.builds(Nack, ids, st.integers(0, 255), st.sampled_from(NackReason)),
    st.builds(UnknownRequest, ids, unknown_operations, st.binary(max_size=24)),
)
