"""Values and numbers written as text (D-RCML-7, D-RCML-14)."""

from __future__ import annotations

import contextlib
import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from rcmlconf.errors import ValueTextError
from rcmlconf.values import (
    DATA_TYPES,
    DataType,
    Kind,
    Scalar,
    format_value_text,
    parse_positive,
    parse_value_text,
)


@pytest.mark.parametrize(
    ("text", "value"),
    [("16e-3", 0.016), ("0.016", 0.016), ("10", 10.0), ("1E-4", 1e-4), ("+2.", 2.0), (".5", 0.5)],
)
def test_positive_numbers(text: str, value: float) -> None:
    assert parse_positive(text) == pytest.approx(value)


@pytest.mark.parametrize(
    "text",
    [
        "0",
        "-1",
        "16ms",
        "INF",
        "inf",
        "NaN",
        "1_0",
        " 1",
        "1 ",
        "0x10",
        "\u0661",
        "",
        "e3",
        "1e400",
        "0.0e5",
    ],
)
def test_not_positive_numbers(text: str) -> None:
    with pytest.raises(ValueTextError):
        parse_positive(text)


@pytest.mark.parametrize(
    ("type_name", "text", "value"),
    [
        ("bool", "true", True),
        ("bool", "0", False),
        ("int8", "-128", -128),
        ("uint64", "18446744073709551615", 2**64 - 1),
        ("int32", "+007", 7),
        ("float64", "-2E3", -2000.0),
        ("float32", "0.1", 0.10000000149011612),
        ("float64", "INF", math.inf),
        ("float64", "-INF", -math.inf),
        ("string", "héllo", "héllo"),
        ("bytes", "00ff", b"\x00\xff"),
        ("bytes", "", b""),
    ],
)
def test_value_texts(type_name: str, text: str, value: object) -> None:
    assert parse_value_text(DATA_TYPES[type_name], text, 8) == value


@pytest.mark.parametrize(
    ("type_name", "text"),
    [
        ("bool", "yes"),
        ("bool", "True"),
        ("int8", "128"),
        ("uint8", "-1"),
        ("int32", "1.0"),
        ("int32", "1_000"),
        ("int32", " 1"),
        ("int32", "٣"),
        ("uint64", "1" + "0" * 5000),
        ("float32", "1e39"),
        ("float64", "1e400"),
        ("float64", "inf"),
        ("float64", "nan"),
        ("string", "123456789"),
        ("bytes", "abc"),
        ("bytes", "zz"),
        ("bytes", "00" * 9),
    ],
)
def test_not_value_texts(type_name: str, text: str) -> None:
    with pytest.raises(ValueTextError):
        parse_value_text(DATA_TYPES[type_name], text, 8)


def test_nan_is_a_float_text() -> None:
    assert math.isnan(parse_value_text(DATA_TYPES["float64"], "NaN"))


@given(st.sampled_from(list(DATA_TYPES.values())), st.text(max_size=30))
def test_any_text_is_a_value_or_a_value_text_error(base: object, text: str) -> None:
    with contextlib.suppress(ValueTextError):
        parse_value_text(base, text, 16)


@given(st.integers(-(2**70), 2**70))
def test_integers_in_range_round_trip_through_text(number: int) -> None:
    base = DATA_TYPES["int64"]
    if base.low <= number <= base.high:
        assert parse_value_text(base, str(number)) == number
    else:
        with pytest.raises(ValueTextError):
            parse_value_text(base, str(number))


def scalars(base: DataType) -> st.SearchStrategy[Scalar]:
    if base.kind is Kind.BOOL:
        return st.booleans()
    if base.kind is Kind.INTEGER:
        return st.integers(base.low, base.high)
    if base.kind is Kind.FLOAT:
        return st.floats(width=32 if base.name == "float32" else 64)
    if base.kind is Kind.STRING:
        return st.text(max_size=20)
    return st.binary(max_size=20)


@given(st.data(), st.sampled_from(list(DATA_TYPES.values())))
def test_every_value_round_trips_through_its_text(data: st.DataObject, base: DataType) -> None:
    value = data.draw(scalars(base))
    text = format_value_text(base, value)
    back = parse_value_text(base, text, 1000)
    if isinstance(value, float) and math.isnan(value):
        assert isinstance(back, float)
        assert math.isnan(back)
    else:
        assert back == value
        assert type(back) is type(value)


@pytest.mark.parametrize(
    ("name", "value", "text"),
    [
        ("float32", 0.30000001192092896, "0.3"),
        ("float64", 0.1, "0.1"),
        ("float32", 2000.0, "2000.0"),
        # Rounded to 4 digits it is past the largest float32 (3.403e38): more digits are needed.
        ("float32", 3.4025001647762064e38, "3.4025002e+38"),
        ("bool", True, "true"),
        ("bytes", b"\x00\xff", "00ff"),
        ("float64", -math.inf, "-INF"),
    ],
)
def test_floats_are_written_with_the_fewest_digits(name: str, value: Scalar, text: str) -> None:
    assert format_value_text(DATA_TYPES[name], value) == text
