"""The binary value format (D-RCML-9 to D-RCML-11) against vectors/values/ and by property."""

from __future__ import annotations

import json
import math
import struct
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from rcmlconf.buffer import Buffer
from rcmlconf.errors import EncodeError, ProtocolError
from rcmlconf.values import DATA_TYPES, Kind, Value, ValueType, lookup_type
from rcmlconf.values.binary import decode_value, encode_value, pull_value, push_value

VECTORS = json.loads(
    (Path(__file__).parents[2] / "vectors" / "values" / "encodings.json").read_text()
)


def value_type(spec: dict[str, object]) -> ValueType:
    base = lookup_type(str(spec["type"]))
    assert base is not None
    return ValueType(base, int(spec.get("count", 1)), int(spec.get("size", 0)))


def from_json(vtype: ValueType, value: object) -> Value:
    if isinstance(value, list):
        return tuple(from_json(ValueType(vtype.base), item) for item in value)
    if vtype.base.kind is Kind.BYTES:
        return bytes.fromhex(str(value))
    if vtype.base.kind is Kind.FLOAT and isinstance(value, str):
        return float(value.replace("INF", "inf"))
    return value


@pytest.mark.parametrize("case", VECTORS["valid"], ids=lambda c: f"{c['type']}={c['value']}")
def test_vector_encodes_and_decodes(case: dict[str, object]) -> None:
    vtype = value_type(case["type"])
    value = from_json(vtype, case["value"])
    data = bytes.fromhex(str(case["hex"]))
    assert encode_value(vtype, value) == data
    assert decode_value(vtype, data) == value


@pytest.mark.parametrize("case", VECTORS["malformed"], ids=lambda c: str(c["why"]))
def test_malformed_vector_fails_where_it_should(case: dict[str, object]) -> None:
    vtype = value_type(case["type"])
    with pytest.raises(ProtocolError) as failure:
        decode_value(vtype, bytes.fromhex(str(case["hex"])))
    assert failure.value.offset == case["offset"]


def test_every_type_has_a_vector() -> None:
    named = {lookup_type(str(c["type"]["type"])).name for c in VECTORS["valid"]}
    assert named == set(DATA_TYPES)


# -- properties ----------------------------------------------------------------------------------


def scalars(vtype: ValueType) -> st.SearchStrategy[Value]:
    base = vtype.base
    if base.kind is Kind.BOOL:
        return st.booleans()
    if base.kind is Kind.INTEGER:
        return st.integers(base.low, base.high)
    if base.kind is Kind.FLOAT:
        width = 32 if base.name == "float32" else 64
        return st.floats(width=width, allow_nan=False)
    if base.kind is Kind.STRING:
        return st.text(max_size=vtype.size).filter(lambda s: len(s.encode()) <= vtype.size)
    return st.binary(max_size=vtype.size)


value_types = st.builds(
    lambda base, count, size: ValueType(base, count, size if base.sized else 0),
    st.sampled_from(list(DATA_TYPES.values())),
    st.integers(1, 5),
    st.integers(1, 40),
)


@st.composite
def typed_values(draw: st.DrawFn) -> tuple[ValueType, Value]:
    vtype = draw(value_types)
    one = scalars(vtype)
    value = draw(st.tuples(*[one] * vtype.count) if vtype.is_array else one)
    return vtype, value


@given(typed_values())
def test_round_trip(case: tuple[ValueType, Value]) -> None:
    vtype, value = case
    data = encode_value(vtype, value)
    assert len(data) <= vtype.max_encoded_size
    assert decode_value(vtype, data) == value


@given(value_types, st.binary(max_size=64))
def test_garbage_raises_only_protocol_error(vtype: ValueType, data: bytes) -> None:
    try:
        decode_value(vtype, data)
    except ProtocolError as error:
        offset = error.offset
    else:
        return
    assert 0 <= offset <= len(data)


@given(typed_values(), st.data())
def test_every_cut_is_reported_where_it_falls(
    case: tuple[ValueType, Value], data: st.DataObject
) -> None:
    vtype, value = case
    encoded = encode_value(vtype, value)
    if not encoded:
        return
    cut = data.draw(st.integers(0, len(encoded) - 1))
    with pytest.raises(ProtocolError) as failure:
        decode_value(vtype, encoded[:cut])
    assert failure.value.offset <= cut


@given(typed_values(), typed_values())
def test_values_follow_one_another_in_one_buffer(
    a: tuple[ValueType, Value], b: tuple[ValueType, Value]
) -> None:
    buf = Buffer()
    push_value(buf, *a)
    push_value(buf, *b)
    reader = Buffer(buf.data())
    assert pull_value(reader, a[0]) == a[1]
    assert pull_value(reader, b[0]) == b[1]
    assert reader.eof()


@pytest.mark.parametrize(
    ("type_name", "value"),
    [
        ("uint8", 256),
        ("int8", -129),
        ("int", True),
        ("bool", 1),
        ("float32", 1e39),
        ("float", "1.0"),
        ("string", b"x"),
        ("bytes", "x"),
    ],
)
def test_values_that_do_not_fit_are_local_errors(type_name: str, value: object) -> None:
    base = lookup_type(type_name)
    assert base is not None
    with pytest.raises(EncodeError):
        encode_value(ValueType(base, 1, 4 if base.sized else 0), value)


def test_strings_longer_than_size_are_refused_both_ways() -> None:
    vtype = ValueType(DATA_TYPES["string"], 1, 3)
    with pytest.raises(EncodeError):
        encode_value(vtype, "four")
    with pytest.raises(ProtocolError):
        decode_value(vtype, b"\x00\x04four")


def test_arrays_need_exactly_count_values() -> None:
    vtype = ValueType(DATA_TYPES["int16"], 3)
    with pytest.raises(EncodeError):
        encode_value(vtype, (1, 2))


def test_nan_survives_as_nan() -> None:
    vtype = ValueType(DATA_TYPES["float64"])
    data = struct.pack(">d", math.nan)
    value = decode_value(vtype, data)
    assert isinstance(value, float)
    assert math.isnan(value)
    assert encode_value(vtype, value) == data
