"""NTP timestamps and the heartbeat clock estimator (D-RCTP-24)."""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from rcmlconf.errors import EncodeError
from rcmlconf.rctp.datastream.clock import (
    NTP_UNIX_OFFSET,
    UNIX_END,
    UNIX_MIN,
    ClockEstimate,
    ClockEstimator,
    ClockSample,
    ntp_difference,
    ntp_from_unix,
    unix_from_ntp,
)

ONE = 1 << 32
#: 2036-02-07T06:28:16Z, where NTP era 0 ends.
ERA_END = (1 << 32) - NTP_UNIX_OFFSET


# -- timestamps ----------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("unix", "ntp"),
    [
        (0.0, NTP_UNIX_OFFSET << 32),  # 1970
        (1748779200.5, 0xEBE6BF40_80000000),  # 2025-06-01T12:00:00.5Z, as in vectors/rctp
        (ERA_END - 0.25, 0xFFFFFFFF_C0000000),  # the era's last quarter second
        (ERA_END, 0),  # era 1 starts again at 0
        (ERA_END + 1.5, 0x00000001_80000000),
        (-1.0, (NTP_UNIX_OFFSET - 1) << 32),  # before 1970 still counts
    ],
)
def test_known_timestamps(unix: float, ntp: int) -> None:
    assert ntp_from_unix(unix) == ntp
    assert unix_from_ntp(ntp) == unix


def test_only_the_eras_the_top_bit_tells_apart() -> None:
    assert unix_from_ntp(1 << 63) == UNIX_MIN  # the first instant of the range: 1968
    for outside in (UNIX_MIN - 1, UNIX_END, math.inf, math.nan):
        with pytest.raises(EncodeError):
            ntp_from_unix(outside)


@given(st.floats(UNIX_MIN, UNIX_END, exclude_max=True))
def test_unix_time_survives_to_the_2_to_the_minus_32(unix: float) -> None:
    assert abs(unix_from_ntp(ntp_from_unix(unix)) - unix) <= 2**-32 + abs(unix) * 2**-52


@given(st.integers(0, (1 << 64) - 1), st.integers(-(1 << 62), 1 << 62))
def test_differences_are_right_across_the_era_end(start: int, units: int) -> None:
    later = (start + units) % (1 << 64)
    assert ntp_difference(later, start) == units / ONE


# -- samples and the estimator -------------------------------------------------------------------

#: A client clock reading near 2025, in 2**-32 s.
client_times = st.integers(0xEB000000 << 32, 0xEC000000 << 32)
#: Up to ±100 s of offset, up to 2 s of one-way delay and of time to answer, in 2**-32 s.
offsets = st.integers(-100 * ONE, 100 * ONE)
delays = st.integers(0, 2 * ONE)


def exchange(t1: int, offset: int, there: int, back: int, answer: int) -> tuple[int, ...]:
    """T1..T4 of one heartbeat with a robot `offset` ahead: every clock exact, in 2**-32 s."""
    t2 = t1 + there + offset
    t3 = t2 + answer
    t4 = t3 - offset + back
    return tuple(t % (1 << 64) for t in (t1, t2, t3, t4))


def test_the_paper_formulas() -> None:
    # Robot 5 s ahead; 100 ms there, 300 ms back, 50 ms to answer.
    t1, t2, t3, t4 = (int(s * ONE) for s in (1000.0, 1005.1, 1005.15, 1000.45))
    sample = ClockSample.from_times(t1, t2, t3, t4)
    assert sample.offset == pytest.approx(((5.1) + (1005.15 - 1000.45)) / 2)
    assert sample.offset == pytest.approx(4.9)  # 5 s, less half the asymmetry (0.2 s / 2)
    assert sample.delay == pytest.approx(0.4)


@given(client_times, offsets, delays, delays)
def test_symmetric_delays_give_the_true_offset(
    t1: int, offset: int, delay: int, answer: int
) -> None:
    sample = ClockSample.from_times(*exchange(t1, offset, delay, delay, answer))
    estimate = ClockEstimator().add(sample)
    truth = offset / ONE
    assert abs(estimate.offset - truth) <= estimate.delay / 2 + 1e-9
    assert estimate.offset == pytest.approx(truth, abs=1e-9)


@given(
    client_times,
    offsets,
    st.lists(st.tuples(delays, delays, delays), min_size=1, max_size=20),
    st.floats(0, 0.01),
)
def test_the_error_never_exceeds_the_stated_uncertainty(
    t1: int, offset: int, legs: list[tuple[int, int, int]], precision: float
) -> None:
    estimator = ClockEstimator(precision)
    truth = offset / ONE
    for index, (there, back, answer) in enumerate(legs):
        start = t1 + index * 10 * ONE  # one heartbeat every 10 s
        estimate = estimator.add(
            ClockSample.from_times(*exchange(start, offset, there, back, answer))
        )
        assert abs(estimate.offset - truth) <= estimate.uncertainty + 1e-9
        assert estimate.uncertainty >= precision


@given(st.lists(st.tuples(st.floats(-5, 5), st.floats(0, 5)), min_size=1, max_size=30))
def test_the_estimate_is_the_smallest_round_trip_of_the_last_eight(
    samples: list[tuple[float, float]],
) -> None:
    estimator = ClockEstimator(precision=0.001)
    for offset, delay in samples:
        estimate = estimator.add(ClockSample(offset, delay))
    recent = samples[-8:]
    best = min(delay for _, delay in recent)
    assert estimate.delay == best
    assert estimate.samples == len(recent)
    assert estimate.offset == next(o for o, d in reversed(recent) if d == best)
    assert estimate.uncertainty == best / 2 + 0.001


def test_a_good_sample_ages_out() -> None:
    estimator = ClockEstimator()
    assert estimator.estimate is None
    estimator.add(ClockSample(1.0, 0.001))
    for _ in range(7):
        assert estimator.add(ClockSample(2.0, 0.5)).offset == 1.0
    assert estimator.add(ClockSample(2.0, 0.5)) == ClockEstimate(2.0, 0.5, 0.25, 8)


def test_a_negative_round_trip_bounds_nothing_below_the_precision() -> None:
    estimate = ClockEstimator(precision=0.002).add(ClockSample(0.5, -0.01))
    assert estimate.delay == -0.01
    assert estimate.uncertainty == 0.002


@pytest.mark.parametrize("precision", [-1.0, math.inf, math.nan])
def test_precision_is_a_finite_number_of_seconds(precision: float) -> None:
    with pytest.raises(ValueError, match="precision"):
        ClockEstimator(precision)
