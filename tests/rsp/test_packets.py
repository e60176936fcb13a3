"""RSP packets (specs/rsp.md §2, §3) against vectors/rsp/packets.json and by property.

The codec has two paths for the payloads of a Device Map: the slots, value by value, and a flat
layout compiled once a map has come back (`maps.COMPILE_AT`). Every test that reads or writes map
packets runs on both: on a fresh codec (slots) and on one that has used the map enough to compile
it (`warm`).
"""

from __future__ import annotations

import contextlib
import importlib.util
import json
import math
import struct
from collections.abc import Callable, Mapping
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest
from hypothesis import given
from hypothesis import strategies as st
from support.rsp_models import CUBO, EVERY_KIND, robot_model

from rcmlconf.errors import EncodeError, ProtocolError
from rcmlconf.rsp.codec import (
    CLEAR_BUFFER,
    Bye,
    ByeReason,
    Encryption,
    Header,
    Hello,
    Item,
    MapBody,
    Packet,
    PacketType,
    Period,
    Refused,
    RefusedReason,
    RspCodec,
    Welcome,
    pull_header,
    push_header,
)
from rcmlconf.rsp.codec.bodies import Body
from rcmlconf.rsp.codec.flat import DECLINED, FlatLayout
from rcmlconf.rsp.codec.header import ANY, HeaderRules
from rcmlconf.rsp.codec.maps import COMPILE_AT, MapPlan
from rcmlconf.rsp.codec.payloads import Slot
from rcmlconf.rsp.layout import Bit, MapPacket, bit
from rcmlconf.rsp.model import DeviceKind, Field, RobotModel
from rcmlconf.values import Kind, Value

ROOT = Path(__file__).resolve().parents[2]
VECTORS_DIR = ROOT / "vectors" / "rsp"
VECTORS = json.loads((VECTORS_DIR / "packets.json").read_text(encoding="utf-8"))
MODELS: dict[str, RobotModel] = {
    key: robot_model((ROOT / "vectors" / path).resolve()) for key, path in VECTORS["models"].items()
}
MAP_TYPES = {
    PacketType.DOWNLINK: MapPacket.DOWNLINK,
    PacketType.UPLINK: MapPacket.UPLINK,
    PacketType.ACK: MapPacket.ACK,
}


def test_the_models_are_the_ones_the_tests_use() -> None:
    expected = {"CUBO": robot_model(CUBO), "every-kind": robot_model(EVERY_KIND)}
    assert expected == MODELS


# -- the vectors' JSON (vectors/rsp/README.md) --------------------------------------------------


def value_json(value: Any) -> Any:
    if isinstance(value, bytes):
        return value.hex()
    if isinstance(value, float) and not math.isfinite(value):
        return "NaN" if math.isnan(value) else ("INF" if value > 0 else "-INF")
    if isinstance(value, tuple | list):
        return [value_json(v) for v in value]
    return value


def item_json(model: RobotModel, item: Item) -> dict[str, Any]:
    shown: dict[str, Any] = {"device": model.devices[item.device].name}
    if item.id is not None:
        shown["id"] = item.id
    if item.values is not None:
        shown["values"] = {name: value_json(v) for name, v in item.values.items()}
    return shown


def body_json(model: RobotModel, body: Body) -> dict[str, Any]:
    if isinstance(body, MapBody):
        return {"items": [item_json(model, item) for item in body.items]}
    if isinstance(body, Refused | Bye):
        return {"reason": body.reason.name}
    if isinstance(body, Period):
        return {"period_ms": body.period_ms}
    shown = {"client_nonce": body.client_nonce.hex()}
    if isinstance(body, Welcome):
        shown["robot_nonce"] = body.robot_nonce.hex()
    return {**shown, "period_ms": body.period_ms, "mac": body.mac.hex()}


def packet_json(model: RobotModel, packet: Packet) -> dict[str, Any]:
    header = packet.header._asdict()
    header["encryption"] = packet.header.encryption.name
    header["type"] = packet.header.type.name
    return {"header": header, "body": body_json(model, packet.body)}


def value_from_json(field: Field, shown: Any) -> Value:
    kind = field.type.base.kind

    def scalar(item: Any) -> Any:
        if kind is Kind.BYTES:
            return bytes.fromhex(item)
        if kind is Kind.FLOAT:
            return {"NaN": math.nan, "INF": math.inf, "-INF": -math.inf}.get(item, item)
        return item

    if field.type.is_array:
        return tuple(scalar(item) for item in shown)
    return scalar(shown)  # type: ignore[no-any-return]


def packet_from_json(model: RobotModel, shown: dict[str, Any]) -> Packet:
    """The Packet a valid vector's JSON describes, built without the codec."""
    fields = dict(shown["header"])
    fields["encryption"] = Encryption[fields["encryption"]]
    fields["type"] = PacketType[fields["type"]]
    header = Header(**fields)
    body = shown["body"]
    built: Body
    if "items" in body:
        items = []
        for item in body["items"]:
            device = model.by_name[item["device"]]
            values = item.get("values")
            if values is not None:
                values = {f.name: value_from_json(f, values[f.name]) for f in device.fields}
            items.append(Item(device.position, item.get("id"), values))
        built = MapBody(tuple(items))
    elif header.type is PacketType.REFUSED:
        built = Refused(RefusedReason[body["reason"]])
    elif header.type is PacketType.BYE:
        built = Bye(ByeReason[body["reason"]])
    elif header.type is PacketType.PERIOD:
        built = Period(body["period_ms"])
    elif header.type is PacketType.HELLO:
        built = Hello(
            bytes.fromhex(body["client_nonce"]), body["period_ms"], bytes.fromhex(body["mac"])
        )
    else:
        built = Welcome(
            bytes.fromhex(body["client_nonce"]),
            bytes.fromhex(body["robot_nonce"]),
            body["period_ms"],
            bytes.fromhex(body["mac"]),
        )
    return Packet(header, built)


# -- a codec fresh or warm ----------------------------------------------------------------------


def warm(codec: RspCodec, packets: list[Packet]) -> RspCodec:
    """The codec with the maps of these packets compiled (`maps.COMPILE_AT`)."""
    for packet in packets:
        for _ in range(COMPILE_AT):
            codec.push_packet(packet)
    return codec


def warmed(key: str) -> RspCodec:
    """A codec that has read and written every valid vector of the model enough to compile it."""
    model = MODELS[key]
    packets = [
        packet_from_json(model, case["packet"]) for case in VECTORS["valid"] if case["model"] == key
    ]
    return warm(RspCodec(model), packets)


CODECS: dict[str, Callable[[str], RspCodec]] = {
    "slots": lambda key: RspCodec(MODELS[key]),
    "flat": warmed,
}


# -- vectors --------------------------------------------------------------------------------------


@pytest.mark.parametrize("path", list(CODECS))
@pytest.mark.parametrize("case", VECTORS["valid"], ids=lambda case: case["name"])
def test_vector_decodes_and_encodes_back(case: dict[str, Any], path: str) -> None:
    model = MODELS[case["model"]]
    codec = CODECS[path](case["model"])
    data = bytes.fromhex(case["hex"])
    packet = codec.pull_packet(data)
    assert packet_json(model, packet) == case["packet"]
    assert codec.push_packet(packet) == data
    assert codec.push_packet(packet_from_json(model, case["packet"])) == data
    # An encrypted session reads the header, opens the body, and reads that (rsp.security).
    header = codec.pull_header(data)
    assert header == packet.header == pull_header(data)
    body = codec.pull_body(header, memoryview(data)[20:])
    assert body_json(model, body) == case["packet"]["body"]
    assert push_header(header) + codec.push_body(header, packet.body) == data


@pytest.mark.parametrize("path", list(CODECS))
@pytest.mark.parametrize("case", VECTORS["malformed"], ids=lambda case: case["name"])
def test_malformed_vector_fails_where_it_should(case: dict[str, Any], path: str) -> None:
    codec = CODECS[path](case["model"])
    data = bytes.fromhex(case["hex"])
    expected = (case["offset"], case["rule"])
    with pytest.raises(ProtocolError) as failure:
        codec.pull_packet(data)
    assert (failure.value.offset, failure.value.rule) == expected
    if failure.value.offset >= 20:  # the header holds: the body alone fails the same way
        header = codec.pull_header(data)
        with pytest.raises(ProtocolError) as again:
            codec.pull_body(header, data[20:])
        assert (again.value.offset, again.value.rule) == expected


def test_the_vectors_are_what_make_packets_writes() -> None:
    spec = importlib.util.spec_from_file_location("make_packets", VECTORS_DIR / "make_packets.py")
    assert spec is not None
    assert spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    assert module.text() == (VECTORS_DIR / "packets.json").read_text(encoding="utf-8")


def test_the_vectors_show_every_kind() -> None:
    """Every packet type, every cell of D-RSP-14's table, the corners of §2."""
    valid = VECTORS["valid"]
    headers = [case["packet"]["header"] for case in valid]
    assert {h["type"] for h in headers} == {t.name for t in PacketType}
    assert {h["encryption"] for h in headers} == {e.name for e in Encryption}
    signed = {
        h["type"]
        for case, h in zip(valid, headers, strict=True)
        if case["packet"]["body"].get("mac")
    }
    assert signed == {"HELLO", "WELCOME"}
    assert {65535, 0} <= {h["sequence"] for h in headers}
    assert 0xFFFFFFFF in {h["timestamp"] for h in headers}
    assert {0, CLEAR_BUFFER, 16, 127} <= {h["buffer"] for h in headers}
    seen = set()
    for case in valid:
        model = MODELS[case["model"]]
        for item in case["packet"]["body"].get("items", []):
            device = model.by_name[item["device"]]
            seen.add((device.kind, case["packet"]["header"]["type"]))
    never = {case["name"] for case in VECTORS["malformed"] if case["name"].startswith("never-")}
    for kind in DeviceKind:
        for packet in MapPacket:
            if bit(kind, packet) is Bit.NEVER:
                words = kind.name.lower().replace("_", "-")
                assert f"never-{words}-in-{packet.value.lower()}" in never
            else:
                assert (kind, packet.value) in seen, (kind, packet)
    sizes = {case["name"]: len(case["hex"]) // 2 for case in valid}
    assert sizes["downlink-music"] == 1992  # D-RSP-8
    assert {"R-RSP-13", "R-RSP-16", "R-RSP-17", "R-RCML-30"} == {
        case["rule"] for case in VECTORS["malformed"]
    }


# -- strategies -----------------------------------------------------------------------------------


def field_values(field: Field) -> st.SearchStrategy[Value]:
    """Any value of the field within its range (D-RCML-9, D-RCML-12)."""
    base = field.type.base
    low, high = field.minimum, field.maximum
    item: st.SearchStrategy[Any]
    if base.kind is Kind.BOOL:
        item = st.booleans()
    elif base.kind is Kind.INTEGER:
        item = st.integers(
            base.low if low is None else max(base.low, int(low)),
            base.high if high is None else min(base.high, int(high)),
        )
    elif base.kind is Kind.FLOAT:
        bounded = low is not None or high is not None
        item = st.floats(
            min_value=low,
            max_value=high,
            allow_nan=not bounded,
            allow_infinity=not bounded,
            width=32 if base.name == "float32" else 64,
        )
    elif base.kind is Kind.STRING:
        size = field.type.size
        item = st.text(st.characters(codec="utf-8"), max_size=min(size, 24)).filter(
            lambda text: len(text.encode("utf-8")) <= size
        )
    else:
        item = st.binary(max_size=min(field.type.size, 48))
    if field.type.is_array:
        return st.tuples(*[item] * field.type.count)
    return item


def payload_values(fields: tuple[Field, ...]) -> st.SearchStrategy[dict[str, Value]]:
    return st.fixed_dictionaries({f.name: field_values(f) for f in fields})


@st.composite
def map_items(draw: st.DrawFn, model: RobotModel, packet: MapPacket) -> tuple[Item, ...]:
    """Any Device Map the table allows for the packet, and its payloads."""
    ids = st.integers(0, (1 << (8 * model.id_length)) - 1)
    items = []
    for device in model.devices:
        meaning = bit(device.kind, packet)
        if meaning is Bit.NEVER or not draw(st.booleans()):
            continue
        ident = draw(ids) if meaning in (Bit.OCCURRENCE, Bit.ID) else None
        values = (
            draw(payload_values(device.fields)) if meaning in (Bit.STATE, Bit.OCCURRENCE) else None
        )
        items.append(Item(device.position, ident, values))
    return tuple(items)


SENDERS = {
    PacketType.HELLO: "local",
    PacketType.WELCOME: "robot",
    PacketType.REFUSED: "robot",
    PacketType.DOWNLINK: "local",
    PacketType.UPLINK: "robot",
    PacketType.ACK: "either",
    PacketType.BYE: "either",
    PacketType.PERIOD: "local",
}
periods = st.integers(5, 10000)
nonces = st.binary(min_size=16, max_size=16)


@st.composite
def packets(draw: st.DrawFn, model: RobotModel) -> Packet:
    kind = draw(st.sampled_from(PacketType))
    encryption = draw(st.sampled_from(Encryption))
    local = st.sampled_from([0, CLEAR_BUFFER])
    robot = st.integers(0, model.command_buffers)
    sender = SENDERS[kind]
    buffer = draw(local if sender == "local" else robot if sender == "robot" else local | robot)
    sessionless = kind in (PacketType.HELLO, PacketType.REFUSED)
    header = Header(
        1,
        model.model_id,
        encryption,
        kind,
        draw(st.integers(0, 0xFFFF)),
        draw(st.integers(0, 0xFFFFFFFF)),
        0 if sessionless else draw(st.integers(1, (1 << 48) - 1)),
        draw(st.integers(0, 0xFFFF)),
        buffer,
    )
    mac = draw(nonces) if encryption is not Encryption.NONE else b""
    body: Body
    if kind in MAP_TYPES:
        body = MapBody(draw(map_items(model, MAP_TYPES[kind])))
    elif kind is PacketType.HELLO:
        body = Hello(draw(nonces), draw(periods), mac)
    elif kind is PacketType.WELCOME:
        body = Welcome(draw(nonces), draw(nonces), draw(periods), mac)
    elif kind is PacketType.REFUSED:
        body = Refused(draw(st.sampled_from(RefusedReason)))
    elif kind is PacketType.BYE:
        body = Bye(draw(st.sampled_from(ByeReason)))
    else:
        body = Period(draw(periods))
    return Packet(header, body)


model_keys = st.sampled_from(sorted(MODELS))
#: One codec per model for the properties: its plans pile up across examples, as a session's do.
SHARED = {key: RspCodec(model) for key, model in MODELS.items()}


def has_nan(value: Any) -> bool:
    if isinstance(value, MapBody):
        return has_nan(value.items)
    if isinstance(value, float):
        return math.isnan(value)
    if isinstance(value, Mapping):
        return any(has_nan(v) for v in value.values())
    if isinstance(value, tuple | list):
        return any(has_nan(v) for v in value)
    return False


def same(model: RobotModel, a: Packet, b: Packet) -> bool:
    """Equal, NaN being equal to NaN."""
    return packet_json(model, a) == packet_json(model, b)


# -- properties -----------------------------------------------------------------------------------


@given(st.data())
def test_round_trip(data: st.DataObject) -> None:
    """Any valid packet of either model round-trips, by the slots and by the flat path."""
    key = data.draw(model_keys)
    model = MODELS[key]
    codec = RspCodec(model)
    packet = data.draw(packets(model))
    encoded = codec.push_packet(packet)
    for _ in range(COMPILE_AT + 1):  # the last use has a compiled layout, if the map can
        assert codec.push_packet(packet) == encoded
        decoded = codec.pull_packet(encoded)
        assert same(model, decoded, packet)
        assert decoded == packet or has_nan(packet.body)
    assert SHARED[key].pull_packet(encoded) == decoded or has_nan(packet.body)


def slot_plan(model: RobotModel, packet: MapPacket, items: tuple[Item, ...]) -> MapPlan:
    slots = [
        Slot(model, model.devices[item.device], bit(model.devices[item.device].kind, packet))
        for item in items
    ]
    positions = [item.device for item in items]
    number = sum(1 << (8 * model.map_size - 1 - p) for p in positions)
    return MapPlan(number.to_bytes(model.map_size), slots, model.id_length)


def fixed_items(model: RobotModel, packet: MapPacket) -> st.SearchStrategy[tuple[Item, ...]]:
    """Items of maps whose payloads all have fixed sizes: those a flat layout takes."""
    return map_items(model, packet).filter(
        lambda items: all(
            not field.type.base.sized
            for item in items
            for field in model.devices[item.device].fields
        )
    )


#: A byte put in a payload: the edges of bools and small ranges, or any.
bytes_at = st.sampled_from([0, 1, 2, 0x7F, 0x80, 0xFF]) | st.integers(0, 255)


@given(st.data())
def test_flat_and_slots_read_alike(data: st.DataObject) -> None:
    """The flat layout reads what the slots read, and declines exactly what they refuse."""
    model = MODELS[data.draw(model_keys)]
    packet = data.draw(st.sampled_from(MapPacket))
    items = data.draw(fixed_items(model, packet))
    plan = slot_plan(model, packet, items)
    flat = FlatLayout(plan.slots, model.id_length, plan.device_map)
    written = plan.push(items)
    assert flat.pack(items) == written
    start = model.map_size
    payloads = bytearray(written[start:])
    for _ in range(data.draw(st.integers(0, 3)) if payloads else 0):
        spot = data.draw(st.integers(0, len(payloads) - 1))
        payloads[spot] = data.draw(bytes_at)
    cut = data.draw(st.sampled_from([0, 0, 0, -1, 1]))
    payloads = payloads[:-1] if cut < 0 else payloads + bytes(cut)
    body = written[:start] + payloads
    try:
        expected = plan.pull(body, start)
    except ProtocolError:
        assert flat.unpack(body, start) is None
    else:
        read = flat.unpack(body, start)
        assert read is not None
        assert [item_json(model, i) for i in read] == [item_json(model, i) for i in expected]


#: Values that are not what a field holds, or not within its range.
odd_values = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(-(1 << 70), 1 << 70),
    st.floats(),
    st.text(max_size=3),
    st.binary(max_size=3),
    st.lists(st.integers(-3, 3), max_size=3),
    st.tuples(st.integers(-3, 3)),
)


@given(st.data())
def test_flat_and_slots_write_alike(data: st.DataObject) -> None:
    """Whatever the slots refuse the flat layout declines; what it writes they write alike."""
    model = MODELS[data.draw(model_keys)]
    packet = data.draw(st.sampled_from(MapPacket))
    items = list(data.draw(fixed_items(model, packet)))
    plan = slot_plan(model, packet, tuple(items))
    flat = FlatLayout(plan.slots, model.id_length, plan.device_map)
    for _ in range(data.draw(st.integers(1, 3))):
        if not items:
            break
        spot = data.draw(st.integers(0, len(items) - 1))
        device, ident, values = items[spot]
        change = data.draw(st.sampled_from(["id", "value", "drop", "extra"]))
        if change == "id":
            ident = data.draw(odd_values)
        elif values is not None and values:
            values = dict(values)
            name = data.draw(st.sampled_from(sorted(values)))
            if change == "value":
                values[name] = data.draw(odd_values)
            elif change == "drop":
                del values[name]
            else:
                values["extra"] = 1
        else:
            values = data.draw(st.none() | st.dictionaries(st.text(max_size=2), odd_values))
        items[spot] = Item(device, ident, values)
    try:
        expected = plan.push(items)
    except EncodeError:
        with contextlib.suppress(*DECLINED):
            assert flat.pack(items) is None
    else:
        try:
            packed = flat.pack(items)
        except DECLINED:
            packed = None
        assert packed in (None, expected)


def decodes_or_fails_cleanly(codec: RspCodec, data: bytes) -> None:
    """A Packet that encodes back to the same bytes, or a ProtocolError inside the datagram."""
    try:
        packet = codec.pull_packet(data)
    except ProtocolError as error:
        offset, rule = error.offset, error.rule
    else:
        if not has_nan(packet.body):
            assert codec.push_packet(packet) == data
        return
    assert 0 <= offset <= len(data)
    assert rule in ("R-RSP-13", "R-RSP-16", "R-RSP-17", "R-RCML-30")


@given(st.data())
def test_every_truncation_is_refused_where_it_falls(data: st.DataObject) -> None:
    key = data.draw(model_keys)
    packet = data.draw(packets(MODELS[key]))
    encoded = SHARED[key].push_packet(packet)
    for cut in range(len(encoded)):
        with pytest.raises(ProtocolError) as failure:
            SHARED[key].pull_packet(encoded[:cut])
        assert failure.value.offset <= cut


@given(st.data())
def test_damaged_packets_give_a_packet_or_a_protocol_error(data: st.DataObject) -> None:
    key = data.draw(model_keys)
    codec = SHARED[key]
    packet = data.draw(packets(MODELS[key]))
    for _ in range(COMPILE_AT):
        damaged = bytearray(codec.push_packet(packet))
    for _ in range(data.draw(st.integers(1, 3))):
        damaged[data.draw(st.integers(0, len(damaged) - 1))] = data.draw(st.integers(0, 255))
    decodes_or_fails_cleanly(codec, bytes(damaged))


@given(model_keys, st.binary(max_size=60))
def test_any_bytes_give_a_packet_or_a_protocol_error(key: str, data: bytes) -> None:
    decodes_or_fails_cleanly(SHARED[key], data)


@given(model_keys, st.sampled_from(PacketType), st.binary(max_size=60))
def test_bytes_after_a_plausible_header_too(key: str, kind: PacketType, rest: bytes) -> None:
    model = MODELS[key]
    session = 0 if kind in (PacketType.HELLO, PacketType.REFUSED) else 1
    head = struct.pack(">BHBBHIHIHB", 1, model.model_id, 0, kind, 0, 0, 0, session, 0, 0)
    decodes_or_fails_cleanly(SHARED[key], head + rest)


@given(st.binary(min_size=20, max_size=20))
def test_a_header_is_read_as_written(data: bytes) -> None:
    """Any 20 bytes: a header that writes back the same, or a fault at a field's offset."""
    try:
        header = pull_header(data)
    except ProtocolError as error:
        offset = error.offset
    else:
        assert push_header(header) == data
        return
    assert offset in (0, 1, 3, 4, 11, 19)


@given(
    st.sampled_from([None, 1, 2, 65535]),
    st.sampled_from([0, 1, 2]),
    st.sampled_from([0, 1, 2, 65534, 65535]),
    st.integers(0, 3),
    st.integers(0, 9),
    st.sampled_from([0, 1, 1 << 40]),
    st.sampled_from([0, 15, 16, 17, 127, 128, 255]),
)
def test_the_header_check_is_the_faults(
    model_id: int | None,
    version: int,
    given_id: int,
    encryption: int,
    kind: int,
    session: int,
    buffer: int,
) -> None:
    """`HeaderRules.pull` checks a header with one expression, `fault` field by field: what the
    one takes the other finds no fault in, for any model's rules and for one model's (16
    command buffers)."""
    rules = ANY if model_id is None else HeaderRules(model_id, 16)
    high, low = divmod(session, 1 << 32)
    data = struct.pack(
        ">BHBBHIHIHB", version, given_id, encryption, kind, 1, 2, high, low, 3, buffer
    )
    try:
        header = rules.pull(data)
    except ProtocolError as error:
        offset = error.offset
    else:
        assert rules.fault(header) is None
        assert rules.push(header) == data
        return
    assert offset in (0, 1, 3, 4, 11, 19)


# -- what cannot be sent --------------------------------------------------------------------------

CUBO_MODEL = MODELS["CUBO"]
DOWN = Header(1, 1, Encryption.NONE, PacketType.DOWNLINK, 1, 2, 3, 4, 0)
UP = DOWN._replace(type=PacketType.UPLINK, buffer=16)
ACK = DOWN._replace(type=PacketType.ACK)
HELLO = DOWN._replace(type=PacketType.HELLO, session_id=0)
MOTION = {"duration": 1, "leftArm": 0, "rightArm": 0, "headTilt": 0}
#: A DOWNLINK that a flat layout takes, and the item each bad case changes.
TYPICAL = (
    Item(0),
    Item(1, None, {"speed": 120}),
    Item(10, None, {"opening": 40}),
    Item(14),
    Item(19),
    Item(22, 3, {"code": 0x20DF}),
    Item(23, 4, MOTION),
)
UPLINK_ITEMS = (
    Item(15, None, {"drop": (True, False)}),
    Item(19, None, {"x": 1.0, "y": 2.0, "heading": 0.5}),
)


def changed(items: tuple[Item, ...], device: int, item: Any) -> tuple[Any, ...]:
    return tuple(item if i.device == device else i for i in items)


BAD_ITEMS: list[tuple[str, Header, tuple[Item, ...], tuple[Any, ...]]] = [
    ("effector without values", DOWN, TYPICAL, changed(TYPICAL, 1, Item(1))),
    ("effector with an ID", DOWN, TYPICAL, changed(TYPICAL, 1, Item(1, 0, {"speed": 1}))),
    ("value above max", DOWN, TYPICAL, changed(TYPICAL, 1, Item(1, None, {"speed": 501}))),
    ("uint8 above max", DOWN, TYPICAL, changed(TYPICAL, 10, Item(10, None, {"opening": 101}))),
    ("uint8 negative", DOWN, TYPICAL, changed(TYPICAL, 10, Item(10, None, {"opening": -1}))),
    ("bool for an int", DOWN, TYPICAL, changed(TYPICAL, 1, Item(1, None, {"speed": True}))),
    ("float for an int", DOWN, TYPICAL, changed(TYPICAL, 1, Item(1, None, {"speed": 1.0}))),
    ("text for an int", DOWN, TYPICAL, changed(TYPICAL, 1, Item(1, None, {"speed": "1"}))),
    ("a value missing", DOWN, TYPICAL, changed(TYPICAL, 1, Item(1, None, {}))),
    ("a value too many", DOWN, TYPICAL, changed(TYPICAL, 1, Item(1, None, {"speed": 1, "x": 1}))),
    ("another value's name", DOWN, TYPICAL, changed(TYPICAL, 1, Item(1, None, {"sped": 1}))),
    ("values not a mapping", DOWN, TYPICAL, changed(TYPICAL, 1, Item(1, None, [("speed", 1)]))),  # type: ignore[arg-type]
    ("a flag with values", DOWN, TYPICAL, changed(TYPICAL, 0, Item(0, None, {}))),
    ("a flag with an ID", DOWN, TYPICAL, changed(TYPICAL, 14, Item(14, 1))),
    ("a request with values", DOWN, TYPICAL, changed(TYPICAL, 19, Item(19, None, {"x": 1.0}))),
    ("a command without ID", DOWN, TYPICAL, changed(TYPICAL, 22, Item(22, None, {"code": 1}))),
    ("a command ID of 256", DOWN, TYPICAL, changed(TYPICAL, 22, Item(22, 256, {"code": 1}))),
    ("a negative command ID", DOWN, TYPICAL, changed(TYPICAL, 22, Item(22, -1, {"code": 1}))),
    ("a bool command ID", DOWN, TYPICAL, changed(TYPICAL, 22, Item(22, True, {"code": 1}))),
    ("a uint16 of 65536", DOWN, TYPICAL, changed(TYPICAL, 22, Item(22, 1, {"code": 65536}))),
    ("duration below min", DOWN, TYPICAL,
     changed(TYPICAL, 23, Item(23, 4, {**MOTION, "duration": 0}))),
    ("an array too short", UP, UPLINK_ITEMS,
     changed(UPLINK_ITEMS, 15, Item(15, None, {"drop": (True,)}))),
    ("an array of ints for bools", UP, UPLINK_ITEMS,
     changed(UPLINK_ITEMS, 15, Item(15, None, {"drop": (1, 0)}))),
    ("a scalar for an array", UP, UPLINK_ITEMS,
     changed(UPLINK_ITEMS, 15, Item(15, None, {"drop": True}))),
    ("NaN where bounded", UP, UPLINK_ITEMS,
     changed(UPLINK_ITEMS, 19, Item(19, None, {"x": 1.0, "y": 2.0, "heading": math.nan}))),
    ("heading above max", UP, UPLINK_ITEMS,
     changed(UPLINK_ITEMS, 19, Item(19, None, {"x": 1.0, "y": 2.0, "heading": 3.2}))),
    ("too large for float32", UP, UPLINK_ITEMS,
     changed(UPLINK_ITEMS, 19, Item(19, None, {"x": 1e39, "y": 2.0, "heading": 0.5}))),
    ("text for a float", UP, UPLINK_ITEMS,
     changed(UPLINK_ITEMS, 19, Item(19, None, {"x": "1", "y": 2.0, "heading": 0.5}))),
    ("not an Item", DOWN, TYPICAL, changed(TYPICAL, 14, (14, None, None))),
    ("an object without ID", DOWN, TYPICAL, changed(TYPICAL, 14, SimpleNamespace(device=14))),
    ("an object without ID, no flat layout", DOWN, (Item(11, None, {"image": b""}),),
     (SimpleNamespace(device=11, values={"image": b""}),)),
    ("bytes above size, no flat layout", DOWN, (Item(11, None, {"image": b""}),),
     (Item(11, None, {"image": bytes(2049)}),)),
    ("a device as a float", DOWN, TYPICAL, changed(TYPICAL, 14, Item(14.0, None, None))),  # type: ignore[arg-type]
    ("a device as a bool", DOWN, TYPICAL[:2], (Item(0), Item(True, None, {"speed": 1}))),
    ("devices out of order", DOWN, TYPICAL, (TYPICAL[1], TYPICAL[0], *TYPICAL[2:])),
    ("a device twice", DOWN, TYPICAL, (TYPICAL[0], *TYPICAL)),
    ("a device past the last", DOWN, TYPICAL, (*TYPICAL, Item(25))),
    ("a negative device", DOWN, TYPICAL, (Item(-1), *TYPICAL)),
    ("an effector in an UPLINK", UP, UPLINK_ITEMS, (Item(1, None, {"speed": 1}), *UPLINK_ITEMS)),
    ("a sensor in an ACK", ACK, (Item(22, 1),), (Item(18), Item(22, 1))),
    ("an ACK with values", ACK, (Item(22, 1),), (Item(22, 1, {"code": 1}),)),
    ("an ACK without ID", ACK, (Item(22, 1),), (Item(22),)),
    ("bytes above size", DOWN, (), (Item(11, None, {"image": bytes(2049)}),)),
    ("text for bytes", DOWN, (), (Item(11, None, {"image": "ab"}),)),
]  # fmt: skip


@pytest.mark.parametrize("path", list(CODECS))
@pytest.mark.parametrize(
    ("header", "good", "bad"), [case[1:] for case in BAD_ITEMS], ids=[case[0] for case in BAD_ITEMS]
)
def test_bad_items_are_a_local_error(
    header: Header, good: tuple[Item, ...], bad: tuple[Any, ...], path: str
) -> None:
    codec = RspCodec(CUBO_MODEL)
    if path == "flat":
        warm(codec, [Packet(header, MapBody(good))])
    with pytest.raises(EncodeError):
        codec.push_packet(Packet(header, MapBody(bad)))
    with pytest.raises(EncodeError):
        codec.push_body(header, MapBody(bad))


NONCE = bytes(16)
BAD_PACKETS: list[tuple[str, Any]] = [
    ("version 2", Packet(DOWN._replace(version=2), MapBody(()))),
    ("another model", Packet(DOWN._replace(model_id=2), MapBody(()))),
    ("encryption 3", Packet(DOWN._replace(encryption=3), MapBody(()))),  # type: ignore[arg-type]
    ("type 9", Packet(DOWN._replace(type=9), MapBody(()))),  # type: ignore[arg-type]
    ("a DOWNLINK without session", Packet(DOWN._replace(session_id=0), MapBody(()))),
    ("a HELLO with a session", Packet(HELLO._replace(session_id=1), Hello(NONCE, 20))),
    ("buffer 1 from the local system", Packet(DOWN._replace(buffer=1), MapBody(()))),
    ("buffer 17 from CUBO", Packet(UP._replace(buffer=17), MapBody(()))),
    ("sequence 65536", Packet(DOWN._replace(sequence=65536), MapBody(()))),
    ("timestamp -1", Packet(DOWN._replace(timestamp=-1), MapBody(()))),
    ("a 49-bit session ID", Packet(DOWN._replace(session_id=1 << 48), MapBody(()))),
    ("a session ID as text", Packet(DOWN._replace(session_id="1"), MapBody(()))),  # type: ignore[arg-type]
    ("last received 65536", Packet(DOWN._replace(last_received=65536), MapBody(()))),
    ("a buffer as text", Packet(DOWN._replace(buffer="0"), MapBody(()))),  # type: ignore[arg-type]
    ("not a header", Packet((1, 2), MapBody(()))),  # type: ignore[arg-type]
    ("not a packet", (DOWN,)),
    ("a HELLO in a DOWNLINK", Packet(DOWN, Hello(NONCE, 20))),
    ("a map body in a HELLO", Packet(HELLO, MapBody(()))),
    ("items not a tuple", Packet(DOWN, MapBody(Item(0)))),  # type: ignore[arg-type]
    ("a MAC without encryption", Packet(HELLO, Hello(NONCE, 20, NONCE))),
    ("no MAC with encryption",
     Packet(HELLO._replace(encryption=Encryption.AES_256_GCM), Hello(NONCE, 20))),
    ("a nonce of 15 bytes", Packet(HELLO, Hello(NONCE[1:], 20))),
    ("a nonce as bytearray", Packet(HELLO, Hello(bytearray(NONCE), 20))),  # type: ignore[arg-type]
    ("a period of 4 ms", Packet(HELLO, Hello(NONCE, 4))),
    ("a period as a bool", Packet(DOWN._replace(type=PacketType.PERIOD), Period(True))),
    ("a period of 10001 ms", Packet(DOWN._replace(type=PacketType.PERIOD), Period(10001))),
    ("REFUSED 0", Packet(HELLO._replace(type=PacketType.REFUSED, buffer=16), Refused(0))),  # type: ignore[arg-type]
    ("BYE 3", Packet(DOWN._replace(type=PacketType.BYE), Bye(3))),  # type: ignore[arg-type]
]  # fmt: skip


@pytest.mark.parametrize(
    "packet", [case[1] for case in BAD_PACKETS], ids=[c[0] for c in BAD_PACKETS]
)
def test_what_cannot_be_sent_is_a_local_error(packet: Any) -> None:
    with pytest.raises(EncodeError):
        RspCodec(CUBO_MODEL).push_packet(packet)


def test_a_map_plan_is_compiled_once_its_map_comes_back() -> None:
    codec = RspCodec(CUBO_MODEL)
    packet = Packet(DOWN, MapBody(TYPICAL))
    data = codec.push_packet(packet)
    maps = codec._maps[PacketType.DOWNLINK]
    (plan,) = maps._plans.values()
    assert plan.flat is None
    for _ in range(COMPILE_AT - 1):
        assert codec.pull_packet(data) == packet
    assert plan.flat is not None
    assert codec.pull_packet(data) == packet
    assert codec.push_packet(packet) == data


def test_a_map_with_bytes_stays_with_the_slots() -> None:
    codec = RspCodec(CUBO_MODEL)
    packet = Packet(DOWN, MapBody((Item(11, None, {"image": b"\x01"}),)))
    data = codec.push_packet(packet)
    for _ in range(COMPILE_AT + 1):
        assert codec.pull_packet(data) == packet
    (plan,) = codec._maps[PacketType.DOWNLINK]._plans.values()
    assert plan.flat is None
