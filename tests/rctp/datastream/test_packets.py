"""Data-stream packets (D-RCTP-19) against vectors/rctp/packets.json and by property.

DATA bodies stay bytes here; test_values.py decodes the vectors' bodies as values.
"""

from __future__ import annotations

import dataclasses
import json
import struct
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given
from hypothesis import strategies as st
from support.datastream import flow_messages

from rcmlconf.errors import EncodeError, ProtocolError
from rcmlconf.rctp.datastream.flow import (
    FlowMessage,
    HeartbeatRequest,
    NackReason,
    Operation,
    encode_flow,
)
from rcmlconf.rctp.datastream.packets import (
    MAX_DATAGRAM,
    MAX_PAYLOADS,
    DataPayload,
    FlowPayload,
    MalformedFlowPayload,
    Packet,
    Payload,
    UnknownPayload,
    body_offsets,
    pull_packet,
    push_packet,
)

VECTORS = json.loads(
    (Path(__file__).parents[3] / "vectors" / "rctp" / "packets.json").read_text(encoding="utf-8")
)
MALFORMED_PACKETS = [case for case in VECTORS["malformed"] if "values" not in case]
TIMES = {"t1", "t2", "t3"}


# -- the vectors' JSON (vectors/rctp/README.md) ------------------------------------------------


def spoken(member: Any) -> Any:
    """`Operation.SET_INTERVAL` -> "set interval"; a number no enum knows stays a number."""
    return member.name.lower().replace("_", " ") if hasattr(member, "name") else member


def flow_json(flow: FlowMessage) -> dict[str, Any]:
    shown: dict[str, Any] = {"message": spoken(flow.message)}
    known = flow.operation in set(Operation)
    shown["operation"] = spoken(Operation(flow.operation)) if known else flow.operation
    for field in dataclasses.fields(flow):
        value = getattr(flow, field.name)
        if field.name == "operation":
            continue
        if field.name in TIMES:
            value = f"{value:016x}"
        elif isinstance(value, bytes):
            value = value.hex()
        shown[field.name] = spoken(value) if field.name in ("direction", "reason") else value
    return shown


def payload_json(payload: Payload) -> dict[str, Any]:
    assert not isinstance(payload, MalformedFlowPayload), "valid vectors hold none"
    if isinstance(payload, DataPayload):
        return {"type": "DATA", "stream": payload.stream, "body": payload.body.hex()}
    if isinstance(payload, FlowPayload):
        return {"type": "FLOW", "stream": payload.stream, "flow": flow_json(payload.flow)}
    return {"type": payload.type, "stream": payload.stream, "body": payload.body.hex()}


def packet_json(packet: Packet) -> dict[str, Any]:
    return {
        "sequence": packet.sequence,
        "tag": f"{packet.tag:08x}",
        "timestamp": f"{packet.timestamp:016x}",
        "payloads": [payload_json(p) for p in packet.payloads],
    }


def without_values(expected: dict[str, Any]) -> dict[str, Any]:
    payloads = [{k: v for k, v in p.items() if k != "values"} for p in expected["payloads"]]
    return {**expected, "payloads": payloads}


# -- vectors -------------------------------------------------------------------------------------


@pytest.mark.parametrize("case", VECTORS["valid"], ids=lambda case: case["name"])
def test_vector_decodes_and_encodes_back(case: dict[str, Any]) -> None:
    data = bytes.fromhex(case["hex"])
    packet = pull_packet(data)
    assert packet_json(packet) == without_values(case["packet"])
    assert push_packet(packet) == data


@pytest.mark.parametrize("case", MALFORMED_PACKETS, ids=lambda case: case["name"])
def test_malformed_vector_fails_where_it_should(case: dict[str, Any]) -> None:
    with pytest.raises(ProtocolError) as failure:
        pull_packet(bytes.fromhex(case["hex"]))
    assert (failure.value.offset, failure.value.rule) == (case["offset"], case["rule"])


@pytest.mark.parametrize("case", VECTORS["malformed_flow"], ids=lambda case: case["name"])
def test_a_broken_flow_body_leaves_the_packet_readable(case: dict[str, Any]) -> None:
    """D-RCTP-22, R-RCTP-53: only broken framing makes a packet unreadable."""
    data = bytes.fromhex(case["hex"])
    packet = pull_packet(data)
    broken = packet.payloads[case["payload"]]
    assert isinstance(broken, MalformedFlowPayload)
    assert (broken.offset, broken.rule) == (case["offset"], case["rule"])
    assert (spoken(broken.answer) if broken.answer else None) == case["answer"]
    assert (broken.request_id is not None) == (case["answer"] is not None)
    assert push_packet(packet) == data


def test_a_well_formed_flow_body_is_not_sent_as_malformed() -> None:
    body = encode_flow(HeartbeatRequest(1, 2))
    with pytest.raises(EncodeError):
        push_packet(Packet(1, 2, 3, (MalformedFlowPayload(0, body, "", 0),)))


@pytest.mark.parametrize(
    "case",
    [case for case in VECTORS["malformed"] if "values" in case],
    ids=lambda case: case["name"],
)
def test_a_bad_data_body_is_no_layout_error(case: dict[str, Any]) -> None:
    """The packet layer cannot see it: the body is wrong only as that access's values."""
    packet = pull_packet(bytes.fromhex(case["hex"]))
    assert isinstance(packet.payloads[case["values"]["payload"]], DataPayload)


def test_the_vectors_show_every_kind() -> None:
    flows = [
        p["flow"] for case in VECTORS["valid"] for p in case["packet"]["payloads"] if "flow" in p
    ]
    kinds = {(f["message"], f["operation"]) for f in flows}
    for message in ("request", "ack"):
        for operation in Operation:
            assert (message, spoken(operation)) in kinds
    assert {f["reason"] for f in flows if "reason" in f} == {spoken(r) for r in NackReason}
    assert any(isinstance(f["operation"], int) for f in flows if f["message"] == "request")
    payloads = [case["packet"]["payloads"] for case in VECTORS["valid"]]
    assert any(isinstance(p["type"], int) for ps in payloads for p in ps)
    assert any(len(ps) == 4 and {p["type"] for p in ps} == {"DATA", "FLOW"} for ps in payloads)
    sequences = {case["packet"]["sequence"] for case in VECTORS["valid"]}
    assert {65534, 65535, 0} <= sequences


# -- properties ----------------------------------------------------------------------------------

streams = st.integers(0, 255)
bodies = st.binary(max_size=40)
payloads: st.SearchStrategy[Payload] = st.one_of(
    st.builds(DataPayload, streams, bodies),
    st.builds(FlowPayload, streams, flow_messages),
    st.builds(
        UnknownPayload, st.integers(0, 255).filter(lambda t: t not in (1, 2)), streams, bodies
    ),
)
packets = st.builds(
    Packet,
    st.integers(0, 0xFFFF),
    st.integers(0, (1 << 32) - 1),
    st.integers(0, (1 << 64) - 1),
    st.lists(payloads, min_size=1, max_size=6).map(tuple),
)


@given(packets)
def test_round_trip(packet: Packet) -> None:
    assert pull_packet(push_packet(packet)) == packet


def decodes_or_fails_cleanly(data: bytes) -> None:
    """A Packet that encodes back to the same bytes, or a ProtocolError inside the datagram."""
    try:
        packet = pull_packet(data)
    except ProtocolError as error:
        offset = error.offset
    else:
        assert push_packet(packet) == data
        return
    assert 0 <= offset <= len(data)


@given(st.binary(max_size=80))
def test_any_bytes_give_a_packet_or_a_protocol_error(data: bytes) -> None:
    decodes_or_fails_cleanly(data)


@given(st.integers(1, 4), st.binary(max_size=80))
def test_bytes_after_a_plausible_header_too(count: int, rest: bytes) -> None:
    decodes_or_fails_cleanly(bytes([2, count]) + bytes(14) + rest)


@given(packets, st.data())
def test_damaged_packets_give_a_packet_or_a_protocol_error(
    packet: Packet, data: st.DataObject
) -> None:
    damaged = bytearray(push_packet(packet))
    for _ in range(data.draw(st.integers(1, 3))):
        damaged[data.draw(st.integers(0, len(damaged) - 1))] = data.draw(st.integers(0, 255))
    decodes_or_fails_cleanly(bytes(damaged))


@given(packets)
def test_every_truncation_is_refused_where_it_falls(packet: Packet) -> None:
    data = push_packet(packet)
    for cut in range(len(data)):
        with pytest.raises(ProtocolError) as failure:
            pull_packet(data[:cut])
        assert failure.value.offset <= cut


@given(packets)
def test_body_offsets_point_at_the_bodies(packet: Packet) -> None:
    data = push_packet(packet)
    for payload, offset in zip(packet.payloads, body_offsets(packet), strict=True):
        body = encode_flow(payload.flow) if isinstance(payload, FlowPayload) else payload.body
        (length,) = struct.unpack_from(">H", data, offset - 2)
        assert data[offset : offset + length] == body


def read(data: bytes | bytearray) -> Packet | tuple[int, str, str | None]:
    """The packet, or where and why it is refused."""
    try:
        return pull_packet(data)
    except ProtocolError as error:
        return error.offset, error.reason, error.rule


@given(
    st.sampled_from([1, 2, 3]),
    st.sampled_from([0, 1, 2]),
    st.sampled_from([0, 1, 2, 3]),
    st.integers(-3, 3),
    st.binary(max_size=12),
)
def test_the_one_data_datagram_reads_as_any_other(
    version: int, count: int, kind: int, skew: int, body: bytes
) -> None:
    """The datagram nearly every one is, one DATA payload that fills it, has a path of its own in
    `pull_packet`; it and its near misses (another version, count, type or length) read as the
    general loop reads them, which reads whatever does not come as `bytes`."""
    length = max(0, len(body) + skew) & 0xFFFF
    datagram = struct.pack(">BBHIQBBH", version, count, 7, 8, 9, kind, 1, length) + body
    for data in (datagram, datagram[:-1], datagram + b"\0"):
        fast, loop = read(data), read(bytearray(data))
        assert fast == loop
        if isinstance(fast, Packet):
            data_bodies = [p.body for p in fast.payloads if isinstance(p, DataPayload)]
            assert all(type(body) is bytes for body in data_bodies)


def test_unknown_payloads_are_skipped_by_their_length() -> None:
    """R-RCTP-51: a receiver that knows only DATA still finds the DATA after them."""
    packet = Packet(1, 2, 3, (UnknownPayload(9, 1, b"\x02\x02\x00\x00"), DataPayload(1, b"\x01")))
    decoded = pull_packet(push_packet(packet))
    assert [p for p in decoded.payloads if isinstance(p, DataPayload)] == [DataPayload(1, b"\x01")]


# -- limits --------------------------------------------------------------------------------------

HEARTBEAT = FlowPayload(0, HeartbeatRequest(1, 2))


def test_a_packet_holds_1_to_255_payloads() -> None:
    data = push_packet(Packet(1, 2, 3, (HEARTBEAT,) * MAX_PAYLOADS))
    assert len(pull_packet(data).payloads) == MAX_PAYLOADS
    for count in (0, MAX_PAYLOADS + 1):
        with pytest.raises(EncodeError):
            push_packet(Packet(1, 2, 3, (HEARTBEAT,) * count))


def test_a_datagram_holds_at_most_65507_bytes() -> None:
    room = MAX_DATAGRAM - 16 - 4
    largest = Packet(1, 2, 3, (DataPayload(1, bytes(room)),))
    data = push_packet(largest)
    assert len(data) == MAX_DATAGRAM
    assert pull_packet(data) == largest
    with pytest.raises(EncodeError):
        push_packet(Packet(1, 2, 3, (DataPayload(1, bytes(room + 1)),)))
    with pytest.raises(ProtocolError) as failure:
        pull_packet(data + b"\x00")
    assert failure.value.offset == MAX_DATAGRAM


@pytest.mark.parametrize(
    "packet",
    [
        Packet(1 << 16, 2, 3, (HEARTBEAT,)),
        Packet(-1, 2, 3, (HEARTBEAT,)),
        Packet(1, 1 << 32, 3, (HEARTBEAT,)),
        Packet(1, 2, 1 << 64, (HEARTBEAT,)),
        Packet(1, 2, 3, (DataPayload(256, b""),)),
        Packet(1, 2, 3, (UnknownPayload(1, 1, b""),)),  # would come back as DATA
        Packet(1, 2, 3, (UnknownPayload(2, 1, b""),)),  # would come back as FLOW, or fail
        Packet(1, 2, 3, (UnknownPayload(256, 1, b""),)),
        Packet(1, 2, 3, (FlowPayload(0, HeartbeatRequest(1 << 16, 0)),)),
        Packet(1, 2, 3, ("not a payload",)),
    ],
    ids=repr,
)
def test_what_cannot_be_sent_is_a_local_error(packet: Packet) -> None:
    with pytest.raises(EncodeError):
        push_packet(packet)
