"""What the plugin shows, against what rcmlconf's codecs decode from the same bytes.

Each `check_*` takes one tshark item (`Layer`: a datagram, a packet, a control message) and the
bytes of it, decodes the bytes with the core codec, and asserts that every field tshark reports is
the codec's value — or, for bytes the codec refuses, that the plugin marks them malformed at the
codec's offset with the codec's rule.
"""

from __future__ import annotations

import dataclasses
import math
import struct
from collections.abc import Sequence

from rcmlconf.buffer import Buffer
from rcmlconf.errors import ProtocolError
from rcmlconf.rctp.datastream.flow import UnknownRequest
from rcmlconf.rctp.datastream.packets import (
    DataPayload,
    FlowPayload,
    MalformedFlowPayload,
    UnknownPayload,
    pull_packet,
)
from rcmlconf.rctp.errors import RemoteProtocolError
from rcmlconf.rctp.messages import Message, Request
from rcmlconf.rctp.reader import MessageReader
from rcmlconf.rsp.codec import MapBody, RspCodec, pull_header
from rcmlconf.rsp.codec.bodies import BODIES, pull_session_body
from rcmlconf.rsp.layout import HEADER_SIZE
from rcmlconf.rsp.model import RobotModel
from rcmlconf.values import Kind, Value
from rcmlconf.wireshark.lua import field_abbreviations
from rcmlconf.wireshark.tshark import Field, Layer


def _number(text: str | None) -> int:
    assert text is not None
    return int(text, 0)


def _children(group: Field) -> dict[str, list[Field]]:
    out: dict[str, list[Field]] = {}
    for item in group.walk():
        out.setdefault(item.name, []).append(item)
    return out


def top_malformed(layer: Layer) -> tuple[int, str | None] | None:
    """The malformed item at the top of an item (not inside a payload): offset and rule."""
    for item in layer.fields:
        if item.name == f"{layer.name}.malformed":
            found = _children(item)
            offset = _number(found[f"{layer.name}.malformed.offset"][0].show)
            rules = found.get(f"{layer.name}.malformed.rule")
            return offset, rules[0].show if rules else None
    return None


def _assert_malformed(layer: Layer, error: ProtocolError) -> None:
    found = top_malformed(layer)
    assert found == (error.offset, error.rule), (found, error.offset, error.rule, error.reason)


# -- the data stream -------------------------------------------------------------------------------


def check_datastream(layer: Layer, data: bytes) -> None:
    try:
        packet = pull_packet(data)
    except ProtocolError as error:
        _assert_malformed(layer, error)
        return
    assert top_malformed(layer) is None
    assert _number(layer.first("rctpds.version")) == 2
    assert _number(layer.first("rctpds.count")) == len(packet.payloads)
    assert _number(layer.first("rctpds.seq")) == packet.sequence
    assert _number(layer.first("rctpds.tag")) == packet.tag
    assert _number(layer.first("rctpds.timestamp")) == packet.timestamp
    groups = layer.groups("rctpds.payload")
    assert len(groups) == len(packet.payloads)
    for group, payload in zip(groups, packet.payloads, strict=True):
        found = _children(group)
        shown = {name: items[0].show for name, items in found.items()}
        assert _number(shown["rctpds.payload.stream"]) == payload.stream
        if isinstance(payload, DataPayload):
            assert shown["rctpds.payload.type"] == "1"
            _assert_bytes(found["rctpds.data"][0], payload.body)
        elif isinstance(payload, UnknownPayload):
            assert _number(shown["rctpds.payload.type"]) == payload.type
            _assert_bytes(found["rctpds.unknown"][0], payload.body)
        elif isinstance(payload, MalformedFlowPayload):
            offset = _number(shown["rctpds.malformed.offset"])
            assert (offset, shown["rctpds.malformed.rule"]) == (payload.offset, payload.rule)
        else:
            assert isinstance(payload, FlowPayload)
            flow = payload.flow
            assert _number(shown["rctpds.flow.message"]) == flow.message
            assert _number(shown["rctpds.flow.operation"]) == flow.operation
            assert _number(shown["rctpds.flow.request_id"]) == flow.request_id
            assert "rctpds.malformed" not in shown
            if isinstance(flow, UnknownRequest):
                if flow.fields:
                    _assert_bytes(found["rctpds.flow.fields"][0], flow.fields)
                continue
            for item in dataclasses.fields(flow):
                if item.name in ("request_id", "operation"):  # the preamble's, checked above
                    continue
                expected = int(getattr(flow, item.name))
                assert _number(shown[f"rctpds.flow.{item.name}"]) == expected, item.name


def _assert_bytes(item: Field, expected: bytes) -> None:
    if expected:
        assert item.value == expected.hex(), (item.name, item.value, expected.hex())
    else:
        assert item.show == ""


# -- RSP -------------------------------------------------------------------------------------------


def check_rsp(layer: Layer, data: bytes, model: RobotModel | None) -> None:
    if model is None:
        _check_rsp_without_model(layer, data)
        return
    codec = RspCodec(model)
    try:
        packet = codec.pull_packet(data)
    except ProtocolError as error:
        _assert_malformed(layer, error)
        return
    assert top_malformed(layer) is None, top_malformed(layer)
    _check_header(layer, packet.header)
    body = packet.body
    if isinstance(body, MapBody):
        _check_items(layer, body, model)
    else:
        _check_session_body(layer, body)


def _check_header(layer: Layer, header: object) -> None:
    version, model_id, encryption, kind, sequence, timestamp, session, last, buffer = header  # type: ignore[misc]
    shown = {
        "version": version,
        "model_id": model_id,
        "encryption": int(encryption),
        "type": int(kind),
        "seq": sequence,
        "timestamp": timestamp,
        "session_id": session,
        "last_received": last,
        "buffer": buffer,
    }
    for name, expected in shown.items():
        assert _number(layer.first(f"rcmlrsp.{name}")) == expected, name


def _check_session_body(layer: Layer, body: object) -> None:
    names = {
        "client_nonce": "rcmlrsp.client_nonce",
        "robot_nonce": "rcmlrsp.robot_nonce",
        "period_ms": "rcmlrsp.period",
        "mac": "rcmlrsp.mac",
    }
    kind = type(body).__name__
    for item in dataclasses.fields(body):  # type: ignore[arg-type]
        value = getattr(body, item.name)
        if item.name == "reason":
            field = "rcmlrsp.refused_reason" if kind == "Refused" else "rcmlrsp.bye_reason"
            assert _number(layer.first(field)) == int(value)
        elif isinstance(value, bytes):
            shown = [f for f in layer.walk() if f.name == names[item.name]]
            if value:
                assert shown, item.name
                assert shown[0].value == value.hex(), item.name
            else:
                assert not shown, item.name
        else:
            assert _number(layer.first(names[item.name])) == value, item.name


def _check_items(layer: Layer, body: MapBody, model: RobotModel) -> None:
    abbreviations = field_abbreviations(model)
    groups = layer.groups("rcmlrsp.device")
    assert [g.show for g in groups] == [model.devices[i.device].name for i in body.items]
    for group, item in zip(groups, body.items, strict=True):
        found = _children(group)
        ids = [f.show for f in found.get("rcmlrsp.id", [])]
        assert ids == ([] if item.id is None else [str(item.id)]), (group.show, ids, item.id)
        device = model.devices[item.device]
        device_abbr, fields_abbr = abbreviations[item.device]
        if item.values is None:
            assert not any(name.startswith("rcmlrsp.dev.") for name in found), group.show
            continue
        for field, field_abbr in zip(device.fields, fields_abbr, strict=True):
            shown = found[f"rcmlrsp.dev.{device_abbr}.{field_abbr}"]
            expected = item.values[field.name]
            items: Sequence[Value] = expected if isinstance(expected, tuple) else (expected,)
            assert len(shown) == len(items), (field.name, len(shown), len(items))
            for tshark, value in zip(shown, items, strict=True):
                _assert_value(field.type.base.kind, field.type.base.name, tshark, value)


def _assert_value(kind: Kind, type_name: str, shown: Field, value: Value) -> None:
    if kind is Kind.BOOL:
        assert shown.show == ("1" if value else "0"), (shown, value)
    elif kind is Kind.INTEGER:
        assert int(shown.show) == value, (shown, value)
    elif kind is Kind.FLOAT:
        assert isinstance(value, float)
        width = 4 if type_name == "float32" else 8
        raw = bytes.fromhex(shown.value or "")
        # The bytes tshark points at are the value's, and its text reads as the same number.
        assert struct.unpack(">f" if width == 4 else ">d", raw)[0] == value or (
            math.isnan(value) and math.isnan(struct.unpack(">f" if width == 4 else ">d", raw)[0])
        )
        text = float(shown.show)
        assert (math.isnan(text) and math.isnan(value)) or math.isclose(
            text, value, rel_tol=1e-5 if width == 4 else 1e-12
        ), (shown.show, value)
    elif kind is Kind.STRING:
        assert isinstance(value, str)
        raw = bytes.fromhex(shown.value or "")
        assert raw[2:].decode("utf-8") == value, shown
        assert len(raw) == 2 + len(value.encode()), shown
    else:
        assert isinstance(value, bytes)
        if value:
            assert shown.value == value.hex(), (shown, value)
        else:
            assert shown.show == "", shown


def _check_rsp_without_model(layer: Layer, data: bytes) -> None:
    """No model: the header by the rules of every model, session bodies, map bodies as bytes."""
    try:
        header = pull_header(data)
    except ProtocolError as error:
        _assert_malformed(layer, error)
        return
    _check_header(layer, header)
    cls = BODIES[header.type]
    if cls is MapBody:
        assert top_malformed(layer) is None
        payload = [f for f in layer.walk() if f.name == "rcmlrsp.payload"]
        if len(data) > HEADER_SIZE:
            assert payload[0].value == data[HEADER_SIZE:].hex()
        else:
            assert not payload
        return
    try:
        body = pull_session_body(cls, header, Buffer(data[HEADER_SIZE:]))  # type: ignore[arg-type]
    except ProtocolError as error:
        moved = ProtocolError(error.reason, HEADER_SIZE + error.offset, error.rule)
        _assert_malformed(layer, moved)
        return
    assert top_malformed(layer) is None
    _check_session_body(layer, body)


# -- RCTP control ----------------------------------------------------------------------------------


def rctp_messages(layers: Sequence[Layer]) -> list[Layer]:
    """The items that are messages or framing failures (not the bytes after one)."""
    return [
        layer
        for layer in layers
        if layer.first("rctp.method") is not None
        or layer.first("rctp.status") is not None
        or top_malformed(layer) is not None
    ]


def check_rctp_stream(layers: Sequence[Layer], data: bytes) -> int:
    """A direction's messages as the plugin shows them, against `MessageReader` on its bytes.
    Returns how many messages the reader read."""
    reader = MessageReader()
    reader.feed(data)
    expected: list[Message | RemoteProtocolError] = []
    while True:
        try:
            message = reader.next_message()
        except RemoteProtocolError as error:
            at = error.offset - reader.offset  # from the message's first byte
            expected.append(RemoteProtocolError(error.reason, at, error.status, error.rule))
            break
        if message is None:
            break
        expected.append(message)
    shown = rctp_messages(layers)
    assert len(shown) == len(expected), ([layer.first("rctp.method") for layer in shown], expected)
    for layer, message in zip(shown, expected, strict=True):
        if isinstance(message, RemoteProtocolError):
            assert top_malformed(layer) == (message.offset, message.rule), (
                top_malformed(layer),
                message,
            )
            continue
        assert top_malformed(layer) is None
        assert layer.first("rctp.version") == message.version
        if isinstance(message, Request):
            assert layer.first("rctp.method") == message.method
            assert layer.first("rctp.target") == message.target
            assert layer.first("rctp.status") is None
        else:
            assert _number(layer.first("rctp.status")) == message.status
            assert layer.first("rctp.phrase") == message.reason
            assert layer.first("rctp.method") is None
        cseq = message.headers.get("CSeq")
        if cseq is not None and cseq.isdigit() and 1 <= int(cseq) < 2**31:
            assert _number(layer.first("rctp.cseq")) == int(cseq)
        else:
            assert layer.first("rctp.cseq") is None
        length = message.headers.get("Content-Length")
        if length is not None:
            assert _number(layer.first("rctp.content_length")) == int(length)
        headers = layer.all("rctp.header")
        assert headers == [f"{name}: {value}" for name, value in message.headers]
        body = [f for f in layer.walk() if f.name == "rctp.body"]
        if message.body:
            assert body[0].value == message.body.hex()
        else:
            assert not body
    return sum(1 for m in expected if not isinstance(m, RemoteProtocolError))
