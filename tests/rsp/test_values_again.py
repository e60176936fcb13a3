"""Values given again (specs/rsp.md D-RSP-14, D-RSP-18): a robot's body reports its sensors every
control tick, mostly what it reported before, and a local system's DOWNLINK carries the same
effector values and bits every beat. What goes out, and what is refused, must not depend on what
was given before: the same as a fresh endpoint's, however alike the values look to Python."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import pytest
from support.rsp_models import robot_model
from support.rsp_pair import Pair, open_pair

from rcmlconf.errors import EncodeError
from rcmlconf.rsp.codec import MapBody, PacketType, RspCodec
from rcmlconf.rsp.session import events
from rcmlconf.rsp.session.robot import RobotEndpoint
from rcmlconf.values import Value

MODEL = robot_model()
NAN = float("nan")
POSE = {"x": 0.0, "y": 1.5, "heading": 0.5}

#: (device, values given first, values given then): equal to Python, or the same objects, but
#: checked or encoded otherwise; and values that did change.
AGAIN = [
    ("battery", {"charge": 80}, {"charge": 80.0}),  # a float is no uint8: refused
    ("battery", {"charge": 1}, {"charge": True}),  # nor a bool
    ("floor", {"drop": (True, False)}, {"drop": (1, 0)}),  # ints are no bools
    ("floor", {"drop": (True, False)}, {"drop": [True, False]}),  # a list: checked again
    ("floor", {"drop": (True, False)}, {"drop": (True, False, True)}),  # count 2: refused
    ("position", POSE, {**POSE, "x": -0.0}),  # the sign of a zero is sent
    ("position", {**POSE, "x": -0.0}, POSE),
    ("position", {**POSE, "x": NAN}, {**POSE, "x": NAN}),
    ("position", POSE, {**POSE, "heading": 4.0}),  # out of range: refused
    ("position", POSE, {"x": 0.0, "y": 1.5}),  # a field missing: refused
    ("position", POSE, {**POSE, "z": 0.0}),
    ("position", POSE, dict(reversed(POSE.items()))),
    ("position", POSE, {**POSE, "y": 2.5}),
    ("battery", {"charge": 80}, {"charge": 80}),
]


def refusal(robot: RobotEndpoint, device: str, values: Mapping[str, Value]) -> str | None:
    try:
        robot.set_state(device, values)
    except (EncodeError, TypeError, KeyError) as exc:
        return type(exc).__name__
    return None


def reported(pair: Pair, device: str) -> str:
    """The newest value of `device` the local system received, exactly (-0.0, NaN): its repr."""
    states = [e for e in pair.local_events if isinstance(e, events.StateReceived)]
    return repr(dict([e for e in states if e.device == device][-1].values))


def session(robot: RobotEndpoint, device: str) -> Pair:
    pair = open_pair(MODEL, robot=robot)
    pair.run_until(0.1)
    pair.local.set_active(device, True)
    return pair


@pytest.mark.parametrize(("device", "first", "then"), AGAIN)
def test_a_state_given_again_is_checked_and_sent_as_a_fresh_one(
    device: str, first: dict[str, Value], then: dict[str, Value]
) -> None:
    fresh, again = RobotEndpoint(MODEL), RobotEndpoint(MODEL)
    fresh_pair, again_pair = session(fresh, device), session(again, device)
    assert refusal(again, device, first) is None
    again_pair.run_until(0.3)
    refused = refusal(fresh, device, then)
    assert refusal(again, device, then) == refused
    fresh_pair.run_until(0.5)
    again_pair.run_until(0.5)
    if refused is None:
        assert reported(again_pair, device) == reported(fresh_pair, device)
    else:  # what was given first stays, as if the refused values never came
        assert reported(again_pair, device) == repr(first)


def test_a_mutable_value_changed_in_place_is_checked_again() -> None:
    """A bytearray given again, the same object, may have changed since it was checked."""
    samples = bytearray(16)
    heard: Any = {"fragment": 1, "samples": samples}  # not a Value: what a body may give anyway
    robot = RobotEndpoint(MODEL)
    robot.set_state("microphone", heard)
    samples.extend(bytes(4096))  # longer than the field's 980 bytes
    with pytest.raises(EncodeError):
        robot.set_state("microphone", heard)


def downlink(pair: Pair) -> list[tuple[str, int | None, object]]:
    """The newest DOWNLINK's items: (device, ID, values)."""
    codec = RspCodec(MODEL)
    for data in reversed(pair.sent_down):
        header, body = codec.pull_packet(data)
        if header.type is PacketType.DOWNLINK:
            assert isinstance(body, MapBody)
            names = [MODEL.devices[item.device].name for item in body.items]
            return [(n, i.id, i.values) for n, i in zip(names, body.items, strict=True)]
    raise AssertionError("no DOWNLINK sent")


def test_every_downlink_carries_what_the_application_set_last() -> None:
    """D-RSP-14, D-RSP-18: a write or a change of the bits is in the next DOWNLINK, and a
    command rides with them, in model order, until acknowledged (D-RSP-17)."""
    pair = open_pair(MODEL)
    pair.run_until(0.1)
    local = pair.local
    local.set_active("base", True)
    local.write("leftWheel", {"speed": 100})
    local.write("rightWheel", {"speed": -100})
    pair.run_until(0.2)
    base = [("base", None, None)]
    assert downlink(pair) == [
        *base,
        ("leftWheel", None, {"speed": 100}),
        ("rightWheel", None, {"speed": -100}),
    ]
    local.write("leftWheel", {"speed": 7})
    local.set_active("rightWheel", False)
    local.set_active("battery", True)
    local.issue("irFire", {"code": 9})
    pair.run_until(pair.now + 0.021)  # the next beat: the ACK comes back after it
    assert downlink(pair) == [
        *base,
        ("leftWheel", None, {"speed": 7}),
        ("battery", None, None),
        ("irFire", 0, {"code": 9}),
    ]
    pair.run_until(pair.now + 0.1)  # acknowledged: the command rides no more
    assert downlink(pair) == [*base, ("leftWheel", None, {"speed": 7}), ("battery", None, None)]
    assert pair.robot.effectors(pair.now)["leftWheel"] == {"speed": 7}
    fired = [e for e in pair.robot_events if isinstance(e, events.OccurrenceReceived)]
    assert [(e.device, e.id) for e in fired] == [("irFire", 0)]
