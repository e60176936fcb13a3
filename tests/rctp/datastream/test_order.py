"""The receiver's sequence rules (D-RCTP-21): newer, duplicate or late, lost, across the wrap."""

from __future__ import annotations

from itertools import pairwise

import pytest
from hypothesis import given
from hypothesis import strategies as st

from rcmlconf.rctp.datastream.order import Arrival, SequenceCounts, SequenceTracker

NEWER, DUPLICATE, LATE = Arrival.NEWER, Arrival.DUPLICATE, Arrival.LATE


def feed(numbers: list[int], tracker: SequenceTracker | None = None) -> list[Arrival]:
    tracker = tracker or SequenceTracker()
    return [tracker.see(number) for number in numbers]


def test_the_first_packet_is_newer_whatever_its_number() -> None:
    for first in (0, 1, 32768, 65535):
        tracker = SequenceTracker()
        assert tracker.highest is None
        assert tracker.see(first) is NEWER
        assert tracker.highest == first


def test_in_order_across_the_wrap() -> None:
    tracker = SequenceTracker()
    assert feed([65533, 65534, 65535, 0, 1], tracker) == [NEWER] * 5
    assert tracker.highest == 1
    assert tracker.counts == SequenceCounts(received=5, newer=5, duplicates=0, late=0, lost=0)


def test_gaps_count_as_lost_until_they_arrive() -> None:
    tracker = SequenceTracker()
    assert feed([65534, 1], tracker) == [NEWER, NEWER]  # 65535 and 0 skipped
    assert tracker.counts.lost == 2
    assert feed([0, 0, 65535, 1, 65534], tracker) == [LATE, DUPLICATE, LATE, DUPLICATE, DUPLICATE]
    assert tracker.counts == SequenceCounts(received=7, newer=2, duplicates=3, late=2, lost=0)


def test_ahead_by_32767_is_newer_and_by_32768_is_not() -> None:
    tracker = SequenceTracker()
    tracker.see(0)
    assert tracker.see(32767) is NEWER
    assert tracker.see(40000) is NEWER
    assert tracker.counts.lost == 39998
    # 7,232 is 32,768 ahead of 40,000 and 32,768 behind it: not newer (RFC 1982 leaves it
    # undefined; D-RCTP-21 counts only 1 to 32,767 as ahead). It was skipped, so it is late.
    assert tracker.see(7232) is LATE
    assert tracker.counts.lost == 39997
    assert tracker.see(7233) is LATE  # behind by 32,767


def test_a_number_from_before_the_first_is_late_and_was_never_lost() -> None:
    tracker = SequenceTracker()
    assert feed([5, 3, 3, 4], tracker) == [NEWER, LATE, DUPLICATE, LATE]
    assert tracker.counts.lost == 0


@pytest.mark.parametrize(
    ("first", "laps"),
    [
        (10, [30010, 60010, 1010]),  # 10 is passed over where the flags wrap: cleared in two parts
        (40000, [4464, 34464, 41000]),  # 40,000 is passed over in one part
    ],
)
def test_a_number_seen_a_lap_ago_is_not_a_duplicate(first: int, laps: list[int]) -> None:
    """Flags of 65,536 numbers ago are forgotten as the highest passes over them."""
    tracker = SequenceTracker()
    tracker.see(first)
    for number in laps:  # round the circle: the highest ends 65,536 + 1,000 after the first
        assert tracker.see(number) is NEWER
    # `first` is now 1,000 behind: the one of this lap was skipped, not seen.
    assert tracker.see(first) is LATE
    assert tracker.see(first) is DUPLICATE


def test_only_16_bit_numbers() -> None:
    with pytest.raises(ValueError, match="16-bit"):
        SequenceTracker().see(65536)


def test_gaps_are_counted_with_the_largest() -> None:
    tracker = SequenceTracker()
    feed([65530, 65531, 65534, 65535, 3, 2, 4], tracker)  # 65532-65533 and 0-2 skipped
    assert tracker.gaps == (2, 3)
    assert tracker.counts.lost == 4  # 2 came late


# -- properties ----------------------------------------------------------------------------------


@st.composite
def arrivals(draw: st.DrawFn) -> tuple[int, list[int]]:
    """A sender's run from `start`, some packets lost, some twice, in a shuffled order, as the
    offsets from `start` (the run is shorter than 32,768, so no offset is ambiguous)."""
    start = draw(st.integers(0, 65535) | st.integers(65535 - 300, 65535))
    length = draw(st.integers(1, 300))
    # The lost as one drawn set, not a coin a packet: 300 draws an example made this file the
    # slowest of the codecs' (the first is never lost: it starts the run).
    lost = draw(st.sets(st.integers(1, 299), max_size=length // 2))
    sent = [i for i in range(length) if i not in lost]
    twice = draw(st.lists(st.sampled_from(sent), max_size=20))
    arrived = sent + twice
    draw(st.randoms(use_true_random=False)).shuffle(arrived)  # not st.permutations: as above
    return start, arrived


@given(arrivals())
def test_verdicts_are_those_of_unwrapped_numbers(case: tuple[int, list[int]]) -> None:
    """With the wrap taken out: newer when above every offset so far; otherwise a duplicate when
    seen before, else late. The tracker must say the same of the wrapped numbers."""
    start, offsets = case
    tracker = SequenceTracker()
    seen: set[int] = set()
    highest = None
    for offset in offsets:
        if highest is None or offset > highest:
            expected, highest = NEWER, offset
        else:
            expected = DUPLICATE if offset in seen else LATE
        seen.add(offset)
        assert tracker.see((start + offset) % 65536) is expected
    assert highest is not None
    assert tracker.highest == (start + highest) % 65536


@given(arrivals())
def test_counts_add_up(case: tuple[int, list[int]]) -> None:
    start, offsets = case
    tracker = SequenceTracker()
    verdicts = feed([(start + offset) % 65536 for offset in offsets], tracker)
    counts = tracker.counts
    distinct = set(offsets)
    assert counts.received == len(offsets) == counts.newer + counts.duplicates + counts.late
    assert counts.duplicates == len(offsets) - len(distinct)
    assert counts.late == len(distinct) - counts.newer
    newer = [offset for offset, verdict in zip(offsets, verdicts, strict=True) if verdict is NEWER]
    assert newer == sorted(set(newer))  # each number newer at most once, and rising
    # Lost: every number from the first to the highest that never arrived.
    first, highest = offsets[0], max(offsets)
    assert counts.lost == sum(1 for n in range(first, highest + 1) if n not in distinct)
    # Gaps: each newer number that is not the one after the newer one before it.
    skips = [b - a - 1 for a, b in pairwise(newer) if b - a > 1]
    assert tracker.gaps == (len(skips), max(skips, default=0))
