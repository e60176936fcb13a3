"""The RCTP/2.0 data stream (specs/rctp-2.0.md §6), sans I/O: bytes and a `now` in, values out.

- `packets`: the datagram (D-RCTP-19): `pull_packet`, `push_packet`, and the payload classes.
- `flow`: FLOW payload bodies (D-RCTP-22): requests, ACKs and NACKs, one class per kind.
- `values`: DATA payload bodies (D-RCTP-20): the values of a stream access for one direction.
- `order`: the receiver's sequence rules (D-RCTP-21): newer, duplicate or late; what was lost.
- `clock`: NTP timestamps and the heartbeat clock estimator (D-RCTP-24).
- `endpoint`: one session's data stream at one end, either role: sends on the beat, answers and
  retries FLOW, watches the receive timeout, keeps a client's clock estimate; `events` what it says.

Parsers let only `ProtocolError` escape, with the offset from the start of the datagram; encoding
something that cannot be sent raises `EncodeError`. Nothing here opens a socket or reads a clock.
"""

from rcmlconf.rctp.datastream.clock import (
    ClockEstimate,
    ClockEstimator,
    ClockSample,
    ntp_difference,
    ntp_from_unix,
    unix_from_ntp,
)
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
    push_flow,
)
from rcmlconf.rctp.datastream.order import Arrival, SequenceCounts, SequenceTracker
from rcmlconf.rctp.datastream.packets import (
    MAX_DATAGRAM,
    MAX_PAYLOADS,
    DataPayload,
    FlowPayload,
    Packet,
    Payload,
    PayloadType,
    UnknownPayload,
    body_offsets,
    pull_packet,
    push_packet,
)
from rcmlconf.rctp.datastream.values import stream_codec

__all__ = [
    "MAX_DATAGRAM",
    "MAX_PAYLOADS",
    "Arrival",
    "ClockEstimate",
    "ClockEstimator",
    "ClockSample",
    "DataPayload",
    "Direction",
    "FlowMessage",
    "FlowPayload",
    "HeartbeatAck",
    "HeartbeatRequest",
    "IntervalGet",
    "IntervalGetAck",
    "IntervalSet",
    "IntervalSetAck",
    "Message",
    "Nack",
    "NackReason",
    "Operation",
    "Packet",
    "Payload",
    "PayloadType",
    "SequenceCounts",
    "SequenceTracker",
    "TimeoutGet",
    "TimeoutGetAck",
    "TimeoutSet",
    "TimeoutSetAck",
    "UnknownPayload",
    "UnknownRequest",
    "body_offsets",
    "decode_flow",
    "encode_flow",
    "ntp_difference",
    "ntp_from_unix",
    "pull_flow",
    "pull_packet",
    "push_flow",
    "push_packet",
    "stream_codec",
    "unix_from_ntp",
]
