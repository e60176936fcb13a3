"""DATA payload bodies (D-RCTP-20): the vectors' bodies as testbot.rcml's values, and properties."""

from __future__ import annotations

import json
from functools import cache
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given
from hypothesis import strategies as st

from rcmlconf.errors import EncodeError, ProtocolError
from rcmlconf.markup.document import XmlDocument, parse_document
from rcmlconf.markup.structure import Checker
from rcmlconf.rcml.loader import load_rcml
from rcmlconf.rcml.model import AccessNode, RcmlDocument
from rcmlconf.rcml.schema import ELEMENTS
from rcmlconf.rctp.bodies import ValuesCodec
from rcmlconf.rctp.datastream.flow import Direction
from rcmlconf.rctp.datastream.packets import DataPayload, body_offsets, pull_packet
from rcmlconf.rctp.datastream.values import stream_codec
from rcmlconf.values import Kind, Value, ValueType

VECTOR_DIR = Path(__file__).parents[3] / "vectors"
VECTORS = json.loads((VECTOR_DIR / "rctp" / "packets.json").read_text(encoding="utf-8"))


@cache
def robot() -> RcmlDocument:
    path = VECTOR_DIR / VECTORS["rcml"]
    document = parse_document(path.read_bytes())
    assert isinstance(document, XmlDocument)
    checker = Checker(document, path.name, ELEMENTS)
    model = load_rcml(checker)
    assert model is not None, [d.to_text() for d in checker.diagnostics()]
    return model


def codec(path: str, direction: str) -> ValuesCodec:
    access = robot().node(path)
    assert isinstance(access, AccessNode)
    return stream_codec(access, Direction[direction.upper()])


def from_json(values: dict[str, Any]) -> dict[str, Value]:
    return {name: tuple(v) if isinstance(v, list) else v for name, v in values.items()}


# -- vectors -------------------------------------------------------------------------------------

DATA_CASES = [
    pytest.param(payload, id=f"{case['name']}-{index}")
    for case in VECTORS["valid"]
    for index, payload in enumerate(case["packet"]["payloads"])
    if payload["type"] == "DATA"
]


@pytest.mark.parametrize("payload", DATA_CASES)
def test_vector_bodies_are_the_values(payload: dict[str, Any]) -> None:
    where = payload["values"]
    values = codec(where["access"], where["direction"])
    body = bytes.fromhex(payload["body"])
    expected = from_json(where["values"])
    assert values.decode(body) == expected
    assert list(values.decode(body)) == list(values.names)  # canonical order
    assert values.encode(expected) == body


@pytest.mark.parametrize(
    "case",
    [case for case in VECTORS["malformed"] if "values" in case],
    ids=lambda case: case["name"],
)
def test_malformed_bodies_fail_where_they_should(case: dict[str, Any]) -> None:
    where = case["values"]
    packet = pull_packet(bytes.fromhex(case["hex"]))
    payload = packet.payloads[where["payload"]]
    assert isinstance(payload, DataPayload)
    base = body_offsets(packet)[where["payload"]]
    with pytest.raises(ProtocolError) as failure:
        codec(where["access"], where["direction"]).decode(payload.body, base)
    assert (failure.value.offset, failure.value.rule) == (case["offset"], case["rule"])


# -- the codec -----------------------------------------------------------------------------------


def test_each_direction_has_its_nodes_in_canonical_order() -> None:
    assert codec("/drive/wheels", "read").names == ("left", "odometry", "right")
    assert codec("/drive/wheels", "write").names == ("left", "right")
    assert codec("/sensors/range", "read").names == ("battery", "ir")
    assert codec("/sensors/range", "write").names == ()


def test_a_direction_without_nodes_has_an_empty_body() -> None:
    values = codec("/sensors/range", "write")
    assert values.encode({}) == b""
    assert values.decode(b"") == {}
    with pytest.raises(ProtocolError) as failure:
        values.decode(b"\x00", 40)
    assert (failure.value.offset, failure.value.rule) == (40, "R-RCTP-40")


@pytest.mark.parametrize(
    "values",
    [
        {"left": 0.5},  # right missing
        {"left": 0.5, "right": 0.5, "odometry": (0.0, 0.0, 0.0)},  # odometry is not writable
        {"left": 0.5, "right": "fast"},
        {"left": 0.5, "right": 1e39},  # no float32
    ],
    ids=repr,
)
def test_what_cannot_be_sent_is_a_local_error(values: dict[str, Value]) -> None:
    with pytest.raises(EncodeError):
        codec("/drive/wheels", "write").encode(values)


def test_a_malformed_value_keeps_its_own_rule() -> None:
    """bool is the type with malformed bytes; testbot's streams have none, so make one."""
    bumpers = robot().node("/sensors/bumpers")
    assert isinstance(bumpers, AccessNode)
    with pytest.raises(ProtocolError) as failure:
        stream_codec(bumpers, Direction.READ).decode(b"\x01\x02", 100)
    assert (failure.value.offset, failure.value.rule) == (101, "R-RCML-30")


def scalars(vtype: ValueType) -> st.SearchStrategy[Value]:
    base = vtype.base
    if base.kind is Kind.FLOAT:
        return st.floats(width=32 if base.name == "float32" else 64, allow_nan=False)
    return st.integers(base.low, base.high)


@st.composite
def bodies(draw: st.DrawFn) -> tuple[ValuesCodec, dict[str, Value]]:
    path, direction = draw(
        st.sampled_from(
            [("/drive/wheels", "read"), ("/drive/wheels", "write"), ("/sensors/range", "read")]
        )
    )
    values = codec(path, direction)
    drawn: dict[str, Value] = {}
    for node in values.nodes:
        one = scalars(node.type)
        drawn[node.name] = draw(st.tuples(*[one] * node.type.count) if node.type.is_array else one)
    return values, drawn


@given(bodies())
def test_round_trip(case: tuple[ValuesCodec, dict[str, Value]]) -> None:
    values, drawn = case
    assert values.decode(values.encode(drawn)) == drawn


@given(bodies(), st.data())
def test_any_other_length_is_refused_inside_the_body(
    case: tuple[ValuesCodec, dict[str, Value]], data: st.DataObject
) -> None:
    values, drawn = case
    body = values.encode(drawn)
    base = data.draw(st.integers(0, 1000))
    changed = data.draw(
        st.one_of(
            st.integers(0, len(body) - 1).map(lambda cut: body[:cut]),
            st.binary(min_size=1, max_size=8).map(lambda extra: body + extra),
        )
    )
    with pytest.raises(ProtocolError) as failure:
        values.decode(changed, base)
    assert base <= failure.value.offset <= base + len(changed)
    assert failure.value.rule == "R-RCTP-40"
