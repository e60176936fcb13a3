"""The scapy RCTP layers against the core codec: every vector of vectors/rctp/packets.json and
every message of vectors/rctp/transcripts decodes to the same fields both ways.

The layers are a second implementation of the wire format (rcmlconf/scapy_layers/rctp.py imports
nothing of rcmlconf.rctp): where the core refuses bytes, the layers must not raise but leave them
to scapy's Raw (or mark a FLOW body malformed, as the core does).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given
from hypothesis import strategies as st
from scapy.packet import Packet, Padding, Raw
from support.scapy_layers import core_messages, layer_message, layer_messages

from rcmlconf.errors import ProtocolError
from rcmlconf.rctp.datastream.flow import Nack, UnknownRequest
from rcmlconf.rctp.datastream.packets import (
    DataPayload,
    FlowPayload,
    MalformedFlowPayload,
    UnknownPayload,
    pull_packet,
)
from rcmlconf.scapy_layers import rctp

ROOT = Path(__file__).resolve().parents[2]
VECTORS = json.loads((ROOT / "vectors" / "rctp" / "packets.json").read_text(encoding="utf-8"))
TRANSCRIPTS = sorted((ROOT / "vectors" / "rctp" / "transcripts").glob("*.json"))


# -- the data stream ------------------------------------------------------------------------------


def core_view(data: bytes) -> dict[str, Any]:
    """What the core codec reads in a datagram, as plain values."""
    packet = pull_packet(data)
    payloads = []
    for payload in packet.payloads:
        if isinstance(payload, DataPayload):
            payloads.append({"kind": "DATA", "stream": payload.stream, "body": payload.body})
        elif isinstance(payload, FlowPayload):
            flow = payload.flow
            fields = {
                name: int(value) if not isinstance(value, bytes) else value
                for name, value in (
                    (n, getattr(flow, n)) for n in flow.__dataclass_fields__ if n != "request_id"
                )
            }
            if not isinstance(flow, Nack | UnknownRequest):
                fields["operation"] = int(flow.operation)
            payloads.append(
                {
                    "kind": "FLOW",
                    "stream": payload.stream,
                    "message": int(flow.message),
                    "request_id": flow.request_id,
                    **fields,
                }
            )
        elif isinstance(payload, MalformedFlowPayload):
            payloads.append(
                {"kind": "malformed FLOW", "stream": payload.stream, "body": payload.body}
            )
        else:
            assert isinstance(payload, UnknownPayload)
            payloads.append({"kind": payload.type, "stream": payload.stream, "body": payload.body})
    return {
        "sequence": packet.sequence,
        "tag": packet.tag,
        "timestamp": packet.timestamp,
        "payloads": payloads,
    }


#: The layer's FLOW fields by the core's names ("direction" and "fields" are taken by scapy's
#: Packet: a field so named would be hidden by the attribute).
_FLOW_FIELDS = {
    "t1": "t1",
    "t2": "t2",
    "t3": "t3",
    "direction": "data_direction",
    "interval": "interval",
    "timeout": "timeout",
    "reason": "reason",
    "fields": "request_fields",
}


def layer_view(packet: rctp.RCTPStream) -> dict[str, Any]:
    """The same, as the scapy layer reads it."""
    payloads = []
    for payload in packet.payloads:
        if isinstance(payload, rctp.RCTPDataPayload):
            payloads.append({"kind": "DATA", "stream": payload.stream, "body": payload.data})
        elif isinstance(payload, rctp.RCTPFlowPayload):
            fields = {
                name: payload.getfieldval(layer_name)
                for name, layer_name in _FLOW_FIELDS.items()
                if layer_name in payload.fields
            }
            payloads.append(
                {
                    "kind": "FLOW",
                    "stream": payload.stream,
                    "message": payload.message,
                    "request_id": payload.request_id,
                    "operation": payload.operation,
                    **fields,
                }
            )
        elif isinstance(payload, rctp.RCTPMalformedFlowPayload):
            payloads.append(
                {"kind": "malformed FLOW", "stream": payload.stream, "body": payload.body}
            )
        else:
            assert type(payload) is rctp.RCTPPayload, payload
            payloads.append({"kind": payload.type, "stream": payload.stream, "body": payload.body})
    return {
        "sequence": packet.seq,
        "tag": packet.tag,
        "timestamp": packet.timestamp,
        "payloads": payloads,
    }


def marks(packet: Packet) -> list[str]:
    """What in a dissection says the bytes do not fit the layout: Raw or Padding anywhere, a
    payload count the payloads do not match, another version."""
    found = []
    layer: Packet | None = packet
    while layer:
        if isinstance(layer, Raw | Padding):
            found.append(type(layer).__name__)
        if isinstance(layer, rctp.RCTPStream):
            if layer.version != rctp.RCTP_STREAM_VERSION:
                found.append("version")
            if layer.count != len(layer.payloads) or not layer.count:
                found.append("count")
            found.extend(type(p).__name__ for p in layer.payloads if isinstance(p, Raw | Padding))
        layer = layer.payload
    return found


VALID = [pytest.param(v, id=v["name"]) for v in VECTORS["valid"]]
MALFORMED = [pytest.param(v, id=v["name"]) for v in VECTORS["malformed"]]
MALFORMED_FLOW = [pytest.param(v, id=v["name"]) for v in VECTORS["malformed_flow"]]


@pytest.mark.parametrize("vector", VALID + MALFORMED_FLOW)
def test_the_layer_reads_each_datagram_as_the_core_does(vector: dict[str, Any]) -> None:
    data = bytes.fromhex(vector["hex"])
    packet = rctp.RCTPStream(data)
    assert layer_view(packet) == core_view(data)
    assert marks(packet) == []
    assert bytes(packet) == data


@pytest.mark.parametrize("vector", VALID)
def test_the_layer_reads_the_vector_as_written(vector: dict[str, Any]) -> None:
    """The vector's own expectation, read field by field, against the layer."""
    expected = vector["packet"]
    packet = rctp.RCTPStream(bytes.fromhex(vector["hex"]))
    assert packet.seq == expected["sequence"]
    assert packet.tag == int(expected["tag"], 16)
    assert packet.timestamp == int(expected["timestamp"], 16)
    assert len(packet.payloads) == len(expected["payloads"])
    for payload, written in zip(packet.payloads, expected["payloads"], strict=True):
        assert payload.stream == written["stream"]
        if written["type"] == "DATA":
            assert payload.data == bytes.fromhex(written["body"])
        elif written["type"] == "FLOW":
            flow = written["flow"]
            assert rctp.RCTP_FLOW_MESSAGES[payload.message].lower() == flow["message"]
            operation = flow["operation"]
            if isinstance(operation, str):
                assert rctp.RCTP_FLOW_OPERATIONS[payload.operation] == operation
            else:
                assert payload.operation == operation
            assert payload.request_id == flow["request_id"]
            for name in ("t1", "t2", "t3"):
                if name in flow:
                    assert payload.getfieldval(name) == int(flow[name], 16)
            for name in ("interval", "timeout"):
                if name in flow:
                    assert payload.getfieldval(name) == flow[name]
            if "direction" in flow:
                assert rctp.RCTP_DIRECTIONS[payload.data_direction] == flow["direction"]
            if "reason" in flow:
                assert rctp.RCTP_NACK_REASONS[payload.reason] == flow["reason"]
            if "fields" in flow:
                assert payload.request_fields == bytes.fromhex(flow["fields"])
        else:
            assert payload.type == written["type"]
            assert payload.body == bytes.fromhex(written["body"])


@pytest.mark.parametrize("vector", MALFORMED_FLOW)
def test_a_broken_flow_body_is_marked_and_the_rest_read(vector: dict[str, Any]) -> None:
    packet = rctp.RCTPStream(bytes.fromhex(vector["hex"]))
    broken = packet.payloads[int(vector["payload"])]
    assert isinstance(broken, rctp.RCTPMalformedFlowPayload)
    others = [p for i, p in enumerate(packet.payloads) if i != int(vector["payload"])]
    assert not any(isinstance(p, rctp.RCTPMalformedFlowPayload) for p in others)


@pytest.mark.parametrize("vector", MALFORMED)
def test_a_datagram_the_core_refuses_is_marked_never_raised(vector: dict[str, Any]) -> None:
    data = bytes.fromhex(vector["hex"])
    packet = rctp.RCTPStream(data)
    assert bytes(packet) == data
    if vector["rule"] == "R-RCTP-40":
        # The layout holds; the DATA body is not the access's values, which only the RCML tells:
        # the layer shows the body's bytes as the core reads them.
        assert layer_view(packet) == core_view(data)
        assert marks(packet) == []
        return
    with pytest.raises(ProtocolError):
        pull_packet(data)
    assert marks(packet), packet.show(dump=True)


@given(st.binary(max_size=200))
def test_any_datagram_dissects_without_raising(data: bytes) -> None:
    packet = rctp.RCTPStream(data)
    assert bytes(packet) == data
    try:
        view = core_view(data)
    except ProtocolError:
        return
    assert layer_view(packet) == view


@given(st.lists(st.tuples(st.integers(0, 3), st.integers(0, 255), st.binary(max_size=30))))
def test_datagrams_of_any_payloads_dissect_as_the_core_reads_them(
    payloads: list[tuple[int, int, bytes]],
) -> None:
    body = b"".join(
        bytes([kind, stream]) + len(data).to_bytes(2, "big") + data
        for kind, stream, data in payloads
    )
    data = bytes([2, len(payloads) % 256]) + bytes(14) + body
    packet = rctp.RCTPStream(data)
    assert bytes(packet) == data
    try:
        view = core_view(data)
    except ProtocolError:
        assert marks(packet)
        return
    assert layer_view(packet) == view


def test_a_packet_built_with_the_layer_is_read_by_the_core() -> None:
    built = rctp.RCTPStream(
        seq=7,
        tag=0xA3F19C07,
        timestamp=0xEBE6BF4080000000,
        payloads=[
            rctp.RCTPDataPayload(stream=1, data=b"\x3f\x00\x00\x00"),
            rctp.RCTPFlowPayload(message=1, operation=1, request_id=3, t1=1, t2=2, t3=3),
            rctp.RCTPFlowPayload(
                message=0, operation=3, request_id=4, data_direction=2, interval=9
            ),
            rctp.RCTPFlowPayload(message=2, operation=9, request_id=5, reason=1),
        ],
    )
    data = bytes(built)
    assert layer_view(rctp.RCTPStream(data)) == core_view(data)


# -- control messages -----------------------------------------------------------------------------


def transcript_wires() -> list[Any]:
    params = []
    for path in TRANSCRIPTS:
        steps = json.loads(path.read_text(encoding="utf-8"))["steps"]
        for number, step in enumerate(steps):
            for key in ("wire", "reply"):
                if step.get(key):
                    params.append(
                        pytest.param(step[key].encode("latin-1"), id=f"{path.stem}-{number}-{key}")
                    )
    return params


WIRES = transcript_wires()


@pytest.mark.parametrize("wire", WIRES)
def test_every_transcript_message_reads_as_the_core_reads_it(wire: bytes) -> None:
    expected, stopped = core_messages(wire)
    packet = rctp.RCTP(wire)
    found, rest = layer_messages(packet)
    assert found == expected
    if stopped is None:
        assert rest is None
    else:  # the core refuses what follows (D-RCTP-10): the layer leaves it to Raw
        assert isinstance(rest, Raw)
        assert rest.load == wire[stopped:]
    assert bytes(packet) == wire


@pytest.mark.parametrize("wire", WIRES)
def test_every_transcript_message_reassembles_from_single_bytes(wire: bytes) -> None:
    """tcp_reassemble fed the stream one byte more at a time, as TCPSession feeds it: None until
    a message is whole; then the whole ones, and Padding for the rest."""
    expected, stopped = core_messages(wire)
    found: list[dict[str, Any]] = []
    buffer = b""
    for byte in wire:
        buffer += bytes([byte])
        metadata: dict[str, Any] = {}
        if len(buffer) < metadata.get("tcp_min_len", 0):
            continue
        result = rctp.RCTP.tcp_reassemble(buffer, metadata, {})
        if result is None:
            continue
        messages, rest = layer_messages(result)
        found.extend(messages)
        if isinstance(rest, Padding):
            buffer = rest.load
        elif isinstance(rest, Raw):
            assert stopped is not None
            buffer = b""
            break
        else:
            buffer = b""
    assert found == expected
    if stopped is None:
        assert buffer == b""


def test_a_body_is_framed_by_content_length() -> None:
    head = b"WRITE /head/control/lcd RCTP/2.0\r\nCSeq: 4\r\nContent-Length: 10\r\n\r\n"
    assert rctp.message_length(head) == len(head) + 10
    assert rctp.message_length(head[:-1]) is None
    assert rctp.RCTP.tcp_reassemble(head + b"12345", {}, {}) is None
    message = rctp.RCTP.tcp_reassemble(head + b"0123456789RCTP/2.0 2", {}, {})
    assert isinstance(message, rctp.RCTPRequest)
    assert message.body == b"0123456789"
    assert message.header("content-length") == "10"
    assert isinstance(message.payload, Padding)
    assert message.payload.load == b"RCTP/2.0 2"


@pytest.mark.parametrize(
    "data",
    [
        b"GET / HTTP/1.1\r\n\r\n",
        b"\x00\x01\x02\x03 binary",
        b"READ / RCTP/2.0\nCSeq: 1\r\n\r\n",
        b"READ / RCTP/2.0\r\nTransfer-Encoding: chunked\r\n\r\n",
        b"RCTP/2.0 200 OK\r\nContent-Length: 99999999\r\n\r\n",
        b"RCTP/2.0 20 OK\r\n",
        b"X" * 5000,
    ],
)
def test_bytes_that_cannot_be_framed_are_raw(data: bytes) -> None:
    assert isinstance(rctp.RCTP(data), Raw)
    assert isinstance(rctp.RCTP.tcp_reassemble(data, {}, {}), Raw)


@given(st.binary(max_size=300))
def test_any_stream_dissects_without_raising(data: bytes) -> None:
    packet = rctp.RCTP(data)
    assert bytes(packet) == data
    rctp.RCTP.tcp_reassemble(data, {}, {})
    expected, _ = core_messages(data)
    found, _ = layer_messages(packet)
    assert found == expected


@given(
    st.lists(
        st.sampled_from(
            [
                b"READ /a RCTP/2.0\r\nCSeq: 1\r\n\r\n",
                b"RCTP/2.0 200 OK\r\nCSeq: 1\r\nContent-Length: 3\r\n\r\nabc",
                b"WRITE /a%20b RCTP/2.0\r\ncseq:2\r\nContent-Length:1\r\n\r\n\x00",
                b"RCTP/2.0 404 Not Found\r\n\r\n",
            ]
        ),
        min_size=1,
        max_size=5,
    ),
    st.binary(max_size=20),
)
def test_pipelined_messages_and_trailing_bytes_read_as_the_core_reads_them(
    messages: list[bytes], tail: bytes
) -> None:
    data = b"".join(messages) + tail
    expected, _ = core_messages(data)
    found, _ = layer_messages(rctp.RCTP(data))
    assert found == expected


def test_a_message_built_with_the_layer_is_read_by_the_core() -> None:
    built = rctp.RCTPResponse(
        status=405,
        reason=b"Method Not Allowed",
        headers=[("CSeq", "3"), ("Allow", "WRITE, STOP, BYE"), ("Content-Length", "2")],
        body=b"no",
    )
    data = bytes(built)
    expected, stopped = core_messages(data)
    assert stopped is None
    assert [layer_message(rctp.RCTP(data))] == expected
    assert expected[0]["headers"][1] == ("Allow", "WRITE, STOP, BYE")
