"""The scapy RSP layers against the core codec: every vector of vectors/rsp/packets.json decodes to
the same header, body, Device Map items and values both ways.

rcmlconf/scapy_layers/rsp.py (with its rsp_model and rsp_device_map) imports nothing of
rcmlconf.rsp.codec: it is a second reading of the wire format. Where the core refuses a packet, the
layer must not raise: what does not fit the layout is left to Raw (or the item list says where it
stops); a value the rules refuse is shown.
"""

from __future__ import annotations

import dataclasses
import enum
import json
import struct
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given
from hypothesis import strategies as st
from scapy.packet import Packet, Padding, Raw
from support.rsp_models import robot_model

from rcmlconf.errors import ProtocolError
from rcmlconf.rsp.codec import (
    Encryption,
    Header,
    Item,
    MapBody,
    PacketType,
    RspCodec,
)
from rcmlconf.rsp.codec import Packet as CorePacket
from rcmlconf.rsp.layout import Bit, MapPacket, bit
from rcmlconf.rsp.model import RobotModel
from rcmlconf.scapy_layers import rsp
from rcmlconf.values import Kind

ROOT = Path(__file__).resolve().parents[2]
VECTORS = json.loads((ROOT / "vectors" / "rsp" / "packets.json").read_text(encoding="utf-8"))
MODELS: dict[str, RobotModel] = {
    key: robot_model((ROOT / "vectors" / path).resolve()) for key, path in VECTORS["models"].items()
}
CUBO = MODELS["CUBO"]

#: Malformed vectors whose fault is in the layout: bytes missing or too many, a type or a bit
#: whose body is unknown (and every R-RSP-17 vector: a bit never set). The others hold a value
#: the rules refuse, which the layer shows.
LAYOUT_FAULTS = {
    "empty",
    "header-cut-short",
    "version-2-short",
    "model-2",
    "type-0",
    "type-9",
    "map-bit-past-last-device",
    "map-cut-short",
    "payload-cut-short",
    "bytes-cut-short",
    "payload-trailing-byte",
    "keepalive-trailing-byte",
    "hello-with-mac-unencrypted",
    "hello-encrypted-without-mac",
    "welcome-mac-cut-short",
    "bye-without-reason",
    "every-kind-where-17-bytes",
    "every-kind-id-cut-short",
}


@pytest.fixture
def use_model() -> Iterator[Any]:
    """Set the layer's model for a test, and set it back after."""
    before = rsp.current_model()
    yield rsp.use_model
    rsp.use_model(before)


def plain(value: Any) -> Any:
    return int(value) if isinstance(value, enum.Enum) else value


def core_view(model: RobotModel, data: bytes) -> dict[str, Any]:
    packet = RspCodec(model).pull_packet(data)
    header = {
        name: plain(getattr(packet.header, name))
        for name in packet.header._fields
        if name != "sequence"
    }
    header["seq"] = packet.header.sequence
    body = packet.body
    if isinstance(body, MapBody):
        shown: Any = [
            (item.device, item.id, repr(dict(item.values)) if item.values is not None else None)
            for item in body.items
        ]
    else:
        shown = {f.name: plain(getattr(body, f.name)) for f in dataclasses.fields(body)}
    return {"header": header, "body": shown}


_BODY_FIELDS = ("client_nonce", "robot_nonce", "period_ms", "mac", "reason")


def layer_view(packet: Packet) -> dict[str, Any]:
    assert isinstance(packet, rsp.RSP), packet
    header = {
        name: packet.getfieldval(name)
        for name in (
            "version",
            "model_id",
            "encryption",
            "type",
            "seq",
            "timestamp",
            "session_id",
            "last_received",
            "buffer",
        )
    }
    body = packet.payload
    shown: Any
    if isinstance(body, rsp.RSPDownlink | rsp.RSPUplink | rsp.RSPAck):
        shown = [
            (item.position, item.id, repr(item.values) if item.values is not None else None)
            for item in body.payloads or ()
        ]
    else:
        shown = {name: body.getfieldval(name) for name in _BODY_FIELDS if name in body.fields}
        if isinstance(body, rsp.RSPHello | rsp.RSPWelcome):
            shown.setdefault("mac", b"")
    return {"header": header, "body": shown}


def marks(packet: Packet) -> list[str]:
    """What in a dissection says the bytes do not fit the layout."""
    found = []
    if isinstance(packet, rsp.RSP) and packet.type in rsp.RSP_TYPES and not packet.payload:
        found.append("no body")
    layer: Packet | None = packet
    while layer:
        if isinstance(layer, Raw | Padding):
            found.append(type(layer).__name__)
        if isinstance(layer, rsp.RSPDownlink | rsp.RSPUplink | rsp.RSPAck):
            found.extend(item.note for item in layer.payloads or () if item.note)
        layer = layer.payload
    return found


VALID = [pytest.param(v, id=v["name"]) for v in VECTORS["valid"]]
MALFORMED = [pytest.param(v, id=v["name"]) for v in VECTORS["malformed"]]


@pytest.mark.parametrize("vector", VALID)
def test_the_layer_reads_each_packet_as_the_core_does(
    vector: dict[str, Any], use_model: Any
) -> None:
    model = MODELS[vector["model"]]
    use_model(model)
    data = bytes.fromhex(vector["hex"])
    packet = rsp.RSP(data)
    assert layer_view(packet) == core_view(model, data)
    assert marks(packet) == []
    assert bytes(packet) == data


@pytest.mark.parametrize("vector", VALID)
def test_item_names_are_the_vectors(vector: dict[str, Any], use_model: Any) -> None:
    use_model(MODELS[vector["model"]])
    packet = rsp.RSP(bytes.fromhex(vector["hex"]))
    expected = vector["packet"]
    assert rsp.RSP_TYPES[packet.type] == expected["header"]["type"]
    if "items" in expected["body"]:
        names = [item.device for item in packet.payload.payloads]
        assert names == [item["device"] for item in expected["body"]["items"]]


@pytest.mark.parametrize("vector", VALID)
def test_without_a_model_the_header_is_read_and_a_map_body_stays_bytes(
    vector: dict[str, Any], use_model: Any
) -> None:
    use_model(None)
    data = bytes.fromhex(vector["hex"])
    packet = rsp.RSP(data)
    view = core_view(MODELS[vector["model"]], data)
    assert layer_view(packet)["header"] == view["header"]
    if isinstance(packet.payload, rsp.RSPDownlink | rsp.RSPUplink | rsp.RSPAck):
        assert "device_map" not in packet.payload.fields
        assert bytes(packet.payload.payload) == data[rsp.RSP_HEADER_SIZE :]
    else:
        assert layer_view(packet)["body"] == view["body"]
    assert bytes(packet) == data


def test_the_model_is_the_one_of_the_header(use_model: Any) -> None:
    """A packet of another model ID is not read with this model's map (D-RSP-6)."""
    use_model(MODELS["every-kind"])
    vector = next(v for v in VECTORS["valid"] if v["name"] == "downlink-typical")
    packet = rsp.RSP(bytes.fromhex(vector["hex"]))
    assert isinstance(packet.payload.payload, Raw)


def test_a_body_keeps_the_model_it_was_read_with(use_model: Any) -> None:
    use_model(CUBO)
    vector = next(v for v in VECTORS["valid"] if v["name"] == "uplink-typical")
    packet = rsp.RSP(bytes.fromhex(vector["hex"]))
    use_model(None)
    copied = packet.copy()
    assert [item.device for item in copied.payload.payloads][:2] == [
        "leftWheelMonitor",
        "rightWheelMonitor",
    ]
    assert "leftWheelMonitor: speed=117" in copied.show(dump=True)
    assert bytes(copied) == bytes(packet)


@pytest.mark.parametrize("vector", MALFORMED)
def test_a_packet_the_core_refuses_is_shown_never_raised(
    vector: dict[str, Any], use_model: Any
) -> None:
    model = MODELS[vector["model"]]
    use_model(model)
    data = bytes.fromhex(vector["hex"])
    with pytest.raises(ProtocolError):
        RspCodec(model).pull_packet(data)
    packet = rsp.RSP(data)
    assert bytes(packet) == data
    packet.show(dump=True)
    if vector["name"] in LAYOUT_FAULTS or vector["rule"] == "R-RSP-17":
        assert marks(packet), packet.show(dump=True)
    else:  # the layout holds: the value the rules refuse is there to see
        assert marks(packet) == [], packet.show(dump=True)


def test_a_sealed_body_is_ciphertext_and_tag(use_model: Any) -> None:
    use_model(CUBO)
    header = struct.pack(">BHBBHIHIHB", 1, 1, 1, 4, 9, 180, 0xA1B2, 0xC3D4E5F6, 8, 0)
    packet = rsp.RSP(header + b"\x01" * 10 + b"\xaa" * 16)
    assert isinstance(packet.payload, rsp.RSPSealed)
    assert packet.payload.ciphertext == b"\x01" * 10
    assert packet.payload.tag == b"\xaa" * 16
    assert marks(packet) == []


def test_a_packet_built_with_the_layer_is_read_by_the_core(use_model: Any) -> None:
    use_model(CUBO)
    left, lip, ir = (CUBO.device(name) for name in ("leftWheel", "lip", "irFire"))
    assert left is not None
    assert lip is not None
    assert ir is not None
    items = [
        rsp.RSPItem(left.position, "leftWheel", values={"speed": -120}),
        rsp.RSPItem(lip.position, "lip", values={"opening": 40}),
        rsp.RSPItem(ir.position, "irFire", id=7, values={"code": 3}),
    ]
    device_map = sum(1 << (8 * 4 - 1 - item.position) for item in items)
    built = rsp.RSP(seq=3, timestamp=60, session_id=0xA1B2C3D4E5F6) / rsp.RSPDownlink(
        device_map=device_map, payloads=items
    )
    data = bytes(built)
    view = core_view(CUBO, data)
    assert view["body"] == [
        (left.position, None, repr({"speed": -120})),
        (lip.position, None, repr({"opening": 40})),
        (ir.position, 7, repr({"code": 3})),
    ]
    assert layer_view(rsp.RSP(data)) == view


@given(st.binary(max_size=120), st.booleans())
def test_any_datagram_dissects_without_raising(data: bytes, with_model: bool) -> None:
    before = rsp.use_model(CUBO if with_model else None)
    try:
        packet = rsp.RSP(data)
        packet.show(dump=True)
        assert bytes(packet) == data
    finally:
        rsp.use_model(before)


@given(
    st.sampled_from([4, 5, 6]),
    st.integers(0, 2**32 - 1),
    st.binary(max_size=60),
)
def test_map_bodies_of_any_bits_dissect_without_raising(
    kind: int, device_map: int, rest: bytes
) -> None:
    buffer = 0 if kind == 4 else 3
    header = struct.pack(">BHBBHIHIHB", 1, 1, 0, kind, 9, 180, 0xA1B2, 0xC3D4E5F6, 8, buffer)
    data = header + device_map.to_bytes(4, "big") + rest
    before = rsp.use_model(CUBO)
    try:
        packet = rsp.RSP(data)
        assert bytes(packet) == data
        try:
            view = core_view(CUBO, data)
        except ProtocolError:
            return
        assert layer_view(packet) == view
    finally:
        rsp.use_model(before)


def _values(field: Any) -> st.SearchStrategy[Any]:
    """Values of a model field within its type, size and range (D-RCML-9 to D-RCML-12)."""
    base, count = field.type.base, field.type.count
    one: st.SearchStrategy[Any]
    if base.kind is Kind.BOOL:
        one = st.booleans()
    elif base.kind is Kind.INTEGER:
        low = base.low if field.minimum is None else max(base.low, int(field.minimum))
        high = base.high if field.maximum is None else min(base.high, int(field.maximum))
        one = st.integers(low, high)
    elif base.kind is Kind.FLOAT:
        bounded = field.minimum is not None or field.maximum is not None
        one = st.floats(
            min_value=field.minimum,
            max_value=field.maximum,
            width=32 if base.width == 4 else 64,
            allow_nan=not bounded,
            allow_infinity=not bounded,
        )
    elif base.kind is Kind.STRING:
        one = st.text(max_size=8).filter(lambda t: len(t.encode()) <= field.type.size)
    else:
        one = st.binary(max_size=min(field.type.size, 24))
    return one if count == 1 else st.tuples(*[one] * count)


@st.composite
def map_packets(draw: st.DrawFn, model: RobotModel) -> tuple[PacketType, list[Item]]:
    """A DOWNLINK, UPLINK or ACK of the model, of any devices its type allows (D-RSP-14)."""
    kind = draw(st.sampled_from([PacketType.DOWNLINK, PacketType.UPLINK, PacketType.ACK]))
    packet = {
        PacketType.DOWNLINK: MapPacket.DOWNLINK,
        PacketType.UPLINK: MapPacket.UPLINK,
        PacketType.ACK: MapPacket.ACK,
    }[kind]
    items = []
    ids = st.integers(0, (1 << (8 * model.id_length)) - 1)
    for device in model.devices:
        meaning = bit(device.kind, packet)
        if meaning is Bit.NEVER or not draw(st.booleans()):
            continue
        ident = draw(ids) if meaning in (Bit.OCCURRENCE, Bit.ID) else None
        values = None
        if meaning in (Bit.STATE, Bit.OCCURRENCE):
            values = {field.name: draw(_values(field)) for field in device.fields}
        items.append(Item(device.position, ident, values))
    return kind, items


@pytest.mark.parametrize("name", sorted(MODELS))
@given(data=st.data())
def test_any_map_packet_the_core_writes_the_layer_reads(name: str, data: st.DataObject) -> None:
    model = MODELS[name]
    kind, items = data.draw(map_packets(model))
    header = Header(1, model.model_id, Encryption.NONE, kind, 5, 100, 0xA1B2C3D4E5F6, 4, 0)
    wire = RspCodec(model).push_packet(CorePacket(header, MapBody(tuple(items))))
    before = rsp.use_model(model)
    try:
        packet = rsp.RSP(wire)
        assert layer_view(packet) == core_view(model, wire)
        assert marks(packet) == []
        assert bytes(packet) == wire
        rebuilt = packet.copy()
        rebuilt.payload.payloads = list(rebuilt.payload.payloads)  # built again from the fields
        assert bytes(rebuilt) == wire
    finally:
        rsp.use_model(before)
