"""The robot's motion filter and audio processor (D-RSP-20, D-RSP-22), with time by hand."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from rcmlconf.rsp.audio import AudioReceiver, FragmentSender
from rcmlconf.rsp.model import Device, DeviceKind, Field, OnLoss, RobotModel
from rcmlconf.rsp.motion import MotionFilter
from rcmlconf.values import DATA_TYPES, ValueType

T = 0.02
WHEEL = Device(
    0,
    "leftWheel",
    DeviceKind.EFFECTOR,
    (Field("speed", ValueType(DATA_TYPES["int16"]), -500, 500),),
    on_loss=OnLoss.ZERO,
)
ARM = Device(
    1, "leftArm", DeviceKind.EFFECTOR, (Field("angle", ValueType(DATA_TYPES["int16"]), -900, 900),)
)
SPEAKER = Device(
    2,
    "speaker",
    DeviceKind.EFFECTOR,
    (
        Field("fragment", ValueType(DATA_TYPES["uint16"])),
        Field("samples", ValueType(DATA_TYPES["bytes"], 1, 4)),
    ),
)
MODEL = RobotModel("bot", 1, (WHEEL, ARM, SPEAKER))


def test_a_value_is_held_until_the_next() -> None:
    motion = MotionFilter(MODEL, T)
    assert motion.output(0.0)["leftWheel"] == {"speed": 0}
    assert motion.output(0.0)["leftArm"] == {"angle": 0}
    motion.receive(ARM, {"angle": 300}, 0, 0.0)
    for now in (0.02, 0.04, 0.5):
        assert motion.output(now)["leftArm"] == {"angle": 300}  # R-RSP-34


def test_values_bunched_in_one_period_collapse_to_the_newest() -> None:
    motion = MotionFilter(MODEL, T)
    for stamp, angle in ((0, 100), (20, 200), (40, 300)):  # three periods' values, one arrival
        motion.receive(ARM, {"angle": angle}, stamp, 0.1)
    assert motion.output(0.1)["leftArm"] == {"angle": 300}


def test_a_value_after_losses_is_reached_over_one_period() -> None:
    motion = MotionFilter(MODEL, T)
    motion.receive(ARM, {"angle": 0}, 0, 0.0)
    motion.receive(ARM, {"angle": 400}, 100, 0.1)  # four packets lost between: a ramp
    assert motion.output(0.1)["leftArm"] == {"angle": 0}
    assert motion.output(0.105)["leftArm"] == {"angle": 100}
    assert motion.output(0.11)["leftArm"] == {"angle": 200}
    assert motion.output(0.12)["leftArm"] == {"angle": 400}  # R-RSP-35
    motion.receive(ARM, {"angle": 500}, 120, 0.12)  # the next on time: no ramp
    assert motion.output(0.12)["leftArm"] == {"angle": 500}


def test_an_effector_with_bytes_is_taken_whole_after_losses() -> None:
    """D-RSP-20, D-RSP-22: a fragment number is never interpolated away from its samples."""
    motion = MotionFilter(MODEL, T)
    motion.receive(SPEAKER, {"fragment": 10, "samples": b"a"}, 0, 0.0)
    motion.receive(SPEAKER, {"fragment": 14, "samples": b"e"}, 80, 0.08)
    assert motion.output(0.09)["speaker"] == {"fragment": 14, "samples": b"e"}


def test_a_lost_link_stops_the_wheels_and_holds_the_arms() -> None:
    motion = MotionFilter(MODEL, T)
    motion.receive(WHEEL, {"speed": 300}, 0, 0.0)
    motion.receive(ARM, {"angle": 300}, 0, 0.0)
    motion.lose_link()
    assert motion.output(0.6)["leftWheel"] == {"speed": 0}
    assert motion.output(0.6)["leftArm"] == {"angle": 300}
    motion.receive(ARM, {"angle": 310}, 600, 0.6)  # the link is back: the wheel stays stopped
    assert motion.output(0.7)["leftWheel"] == {"speed": 0}


def test_fragments_are_played_in_order_and_gaps_counted() -> None:
    receiver = AudioReceiver()
    for fragment, samples in ((0, b"a"), (1, b"b"), (3, b"d"), (2, b"c"), (3, b"d"), (4, b"e")):
        receiver.receive(fragment, samples)
    assert bytes(receiver.sound) == b"abde"
    counts = receiver.counts
    assert (counts.played, counts.gaps, counts.late, counts.duplicates) == (4, 1, 1, 1)


@given(st.lists(st.binary(max_size=50), max_size=20), st.integers(1, 17))
def test_a_sound_cut_into_fragments_plays_back_whole(pieces: list[bytes], size: int) -> None:
    sender, receiver = FragmentSender(size), AudioReceiver()
    for piece in pieces:
        for fragment, samples in sender.feed(piece):
            assert len(samples) == size
            receiver.receive(fragment, samples)
    for fragment, samples in sender.flush():
        receiver.receive(fragment, samples)
    assert bytes(receiver.sound) == b"".join(pieces)
    assert receiver.counts.gaps == 0


def test_fragment_numbers_wrap() -> None:
    receiver = AudioReceiver()
    for fragment in (65534, 65535, 0, 1):
        assert receiver.receive(fragment, b"x")
    assert receiver.counts.gaps == 0
    with pytest.raises(ValueError, match="at least one byte"):
        FragmentSender(0)
