"""Impairment specs: the grammar, the canonical text, and every error with its column."""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from rcmlconf.errors import RcmlconfError
from rcmlconf.impair.spec import (
    KEYS,
    MOST_BURST,
    MOST_TIME,
    Impairment,
    ImpairmentError,
    parse_impairment,
)

FULL = "loss=5%,burst=3,delay=40ms,jitter=10ms,reorder=2%,duplicate=1%,corrupt=0.1%"


def test_the_full_example_parses_and_reads_back_the_same() -> None:
    imp = parse_impairment(FULL)
    assert imp == Impairment(
        loss=0.05,
        burst=3,
        delay=0.040,
        jitter=0.010,
        reorder=0.02,
        duplicate=0.01,
        corrupt=0.001,
    )
    assert str(imp) == FULL
    assert imp.reorder_gap == pytest.approx(0.050)  # one more delay + jitter span


@pytest.mark.parametrize("text", ["", "   ", "none", "NONE", " none "])
def test_no_impairment(text: str) -> None:
    imp = parse_impairment(text)
    assert imp == Impairment()
    assert imp.is_none
    assert str(imp) == "none"


@pytest.mark.parametrize(
    ("text", "expected", "canonical"),
    [
        ("loss=0.05", Impairment(loss=0.05), "loss=5%"),
        ("loss=5%", Impairment(loss=0.05), "loss=5%"),
        ("loss=100%", Impairment(loss=1.0), "loss=100%"),
        ("loss=1", Impairment(loss=1.0), "loss=100%"),
        ("loss=0%", Impairment(), "none"),
        ("delay=0", Impairment(), "none"),
        ("delay=1s", Impairment(delay=1.0), "delay=1000ms"),
        ("delay=500us", Impairment(delay=0.0005), "delay=0.5ms"),
        ("delay=.5ms", Impairment(delay=0.0005), "delay=0.5ms"),
        ("delay=2.5e1ms", Impairment(delay=0.025), "delay=25ms"),
        (" Delay = 40 MS , LOSS=5 %", Impairment(delay=0.04, loss=0.05), "loss=5%,delay=40ms"),
        ("corrupt=0.1%,loss=1%", Impairment(corrupt=0.001, loss=0.01), "loss=1%,corrupt=0.1%"),
        ("gap=0ms,reorder=5%", Impairment(reorder=0.05, gap=0.0), "reorder=5%,gap=0ms"),
        ("burst=1.5,loss=10%", Impairment(loss=0.1, burst=1.5), "loss=10%,burst=1.5"),
        ("loss=50%,burst=1", Impairment(loss=0.5, burst=1), "loss=50%,burst=1"),
        ("loss=100%,burst=2", Impairment(loss=1.0, burst=2), "loss=100%,burst=2"),
        ("jitter=-0ms", Impairment(), "none"),
    ],
)
def test_valid_specs(text: str, expected: Impairment, canonical: str) -> None:
    imp = parse_impairment(text)
    assert imp == expected
    assert str(imp) == canonical
    assert parse_impairment(canonical) == imp


def test_is_none_means_no_effect() -> None:
    assert parse_impairment("gap=5ms,burst=2").is_none
    assert not parse_impairment("jitter=1us").is_none
    assert not parse_impairment("corrupt=0.001%").is_none


def test_the_default_gap() -> None:
    assert parse_impairment("reorder=1%").reorder_gap == 0.010
    assert parse_impairment("reorder=1%,delay=2ms").reorder_gap == 0.010  # at least 10 ms
    assert parse_impairment("reorder=1%,delay=40ms,jitter=5ms").reorder_gap == pytest.approx(0.045)
    assert parse_impairment("reorder=1%,delay=40ms,gap=3ms").reorder_gap == 0.003


def test_a_value_that_is_not_exact_in_percent_or_ms_is_written_so_it_reads_back() -> None:
    imp = Impairment(loss=0.1 + 0.2, delay=0.1 + 0.2)  # 0.30000000000000004
    assert parse_impairment(str(imp)) == imp


ERRORS = [
    # (spec, column, words in the message)
    ("loss=5%,foo=1", 9, ["unknown key 'foo'", ", ".join(KEYS)]),
    ("lost=5%", 1, ["unknown key 'lost'", "loss, burst, delay"]),
    ("loss=abc", 6, ["bad number 'abc'", "loss=5%"]),
    ("delay=fast", 7, ["bad number 'fast'", "delay=40ms"]),
    ("burst=many,loss=1%", 7, ["bad number 'many'", "burst=3"]),
    ("loss=", 6, ["empty value"]),
    ("loss=150%", 6, ["not a probability in 0..1"]),
    ("loss=5", 6, ["not a probability in 0..1", "did you mean loss=5%?"]),
    ("duplicate=-1%", 11, ["not a probability in 0..1"]),
    ("corrupt=1.01", 9, ["not a probability in 0..1"]),
    ("reorder=5 percent", 9, ["bad probability"]),
    ("delay=-5ms", 7, ["negative time"]),
    ("jitter=-1us", 8, ["negative time"]),
    ("loss=1%, gap=-2s", 14, ["negative time"]),
    ("delay=5", 7, ["needs a unit"]),
    ("delay=5m", 7, ["unknown unit 'm'"]),
    ("delay=1e400s", 7, ["too large"]),
    ("burst=0.5", 7, ["at least 1"]),
    ("burst=1001,loss=1%", 7, ["at most 1,000"]),
    ("delay=1e9ms", 7, ["delay=1e9ms is longer than delay may be", "0 to 10 s"]),
    ("jitter=10.001s", 8, ["jitter=10.001s is longer", "0 to 10 s"]),
    ("loss=1%,gap=10001ms", 13, ["gap=10001ms is longer"]),
    ("loss=99.95%,burst=1000", 19, ["needs burst=1999 or more, more than burst may be (1,000)"]),
    ("burst=3ms", 7, ["without a unit"]),
    ("loss=60%,burst=1", 16, ["impossible", "at most 50% loss", "burst=1.5 or more"]),
    ("loss=5%,,delay=1ms", 9, ["empty item"]),
    ("loss=5%,", 9, ["empty item"]),
    ("loss=1%,loss=2%", 9, ["loss given twice", "first at column 6"]),
    ("none,loss=1%", 1, ["none stands alone"]),
    ("loss=1%,  delay", 11, ["expected KEY=VALUE"]),
    ("=5%", 1, ["missing key"]),
]


@pytest.mark.parametrize(("text", "column", "words"), ERRORS)
def test_errors_say_where_and_why(text: str, column: int, words: list[str]) -> None:
    with pytest.raises(ImpairmentError) as caught:
        parse_impairment(text)
    error = caught.value
    assert isinstance(error, RcmlconfError)
    assert error.column == column
    assert str(error).startswith(f"column {column}: ")
    for word in words:
        assert word in error.reason


@pytest.mark.parametrize(
    "kwargs",
    [
        {"loss": 1.5},
        {"reorder": -0.1},
        {"delay": -1.0},
        {"jitter": math.inf},
        {"gap": math.nan},
        {"burst": 0.0},
        {"burst": 1e4},
        {"delay": 10.5},
        {"jitter": 1e9},
        {"gap": 11.0},
        {"loss": 0.9, "burst": 2.0},
    ],
)
def test_an_impairment_built_directly_is_checked_too(kwargs: dict[str, float]) -> None:
    with pytest.raises(ImpairmentError) as caught:
        Impairment(**kwargs)
    assert caught.value.column is None


probabilities = st.floats(0.0, 1.0, allow_nan=False) | st.sampled_from([0.0, 0.01, 0.05, 1.0])
times = st.floats(0.0, MOST_TIME) | st.sampled_from([0.0, 0.001, 0.04, 5e-324, MOST_TIME])


@st.composite
def impairments(draw: st.DrawFn) -> Impairment:
    loss = draw(probabilities)
    burst = None
    least = max(1.0, loss / (1.0 - loss)) if loss < 1.0 else 1.0
    if least <= MOST_BURST and draw(st.booleans()):
        burst = draw(st.floats(least, MOST_BURST))
    return Impairment(
        loss=loss,
        burst=burst,
        delay=draw(times),
        jitter=draw(times),
        reorder=draw(probabilities),
        gap=draw(st.none() | times),
        duplicate=draw(probabilities),
        corrupt=draw(probabilities),
    )


@given(impairments())
def test_the_canonical_spec_reads_back_as_the_same_impairment(imp: Impairment) -> None:
    text = str(imp)
    again = parse_impairment(text)
    assert again == imp
    assert str(again) == text


@given(st.text(alphabet="lossburstdelayjitterreordergapduplicatecorruptnme0123456789.%=,- +"))
def test_any_text_parses_or_raises_only_impairment_error(text: str) -> None:
    column: int | None = 0
    try:
        imp = parse_impairment(text)
    except ImpairmentError as error:
        column = error.column
    else:
        assert parse_impairment(str(imp)) == imp
    assert column is not None
    assert 0 <= column <= len(text) + 1
