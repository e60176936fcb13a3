"""The simulated CUBO (rcmlconf.reference.rsp.cubo): kinematics, servos, sensors, events,
determinism; and the speaker as the reference robot's audio processor plays it."""

from __future__ import annotations

import itertools
import math
import statistics

import pytest
from support.rsp_models import EVERY_KIND, robot_model

from rcmlconf.reference.drivers.room import WHEEL_BASE, Pose
from rcmlconf.reference.rsp.bodies import GenericBody
from rcmlconf.reference.rsp.cubo import (
    BUTTONS,
    CHARGE,
    DIP_DEPTH,
    DIP_GAP,
    LOW_BATTERY,
    LOW_CHARGE,
    PRESS_GAP,
    PRESS_HOLD,
    PRESSED,
    RATES,
    WHEEL_ACCELERATION,
    CuboBody,
)
from rcmlconf.reference.rsp.robot import ReferenceRobot, RobotSettings
from rcmlconf.rsp.model import DeviceKind
from rcmlconf.rsp.session import events
from rcmlconf.rsp.session.robot import RobotEndpoint


def wheels(left: int, right: int) -> dict[str, dict[str, int]]:
    return {"leftWheel": {"speed": left}, "rightWheel": {"speed": right}}


def test_it_drives_straight_after_accelerating() -> None:
    body = CuboBody(robot_model())
    body.apply(wheels(200, 200), 0.0)
    body.advance(1.0)
    ramp = 0.2 / WHEEL_ACCELERATION  # 0.1 s to reach 0.2 m/s, 1 cm on the way
    expected = 0.2 * ramp / 2 + 0.2 * (1.0 - ramp)
    assert body.pose.x == pytest.approx(expected, abs=1e-9)
    assert body.pose.y == pytest.approx(0.0, abs=1e-12)
    assert body.pose.heading == pytest.approx(0.0, abs=1e-12)


def test_it_turns_on_the_spot_and_along_arcs() -> None:
    body = CuboBody(robot_model(), Pose(1.0, 2.0, 0.0))
    body.apply(wheels(-100, 100), 0.0)
    body.advance(2.0)
    ramp = 0.1 / WHEEL_ACCELERATION
    turn = 0.2 / WHEEL_BASE  # rad/s at full speed
    assert body.pose.heading == pytest.approx(turn * (2.0 - ramp / 2), abs=1e-9)
    assert (body.pose.x, body.pose.y) == pytest.approx((1.0, 2.0), abs=1e-9)
    # A full circle of radius r at constant speeds comes back where it began.
    circle = CuboBody(robot_model())
    circle.apply(wheels(100, 300), 0.0)
    circle.advance(0.2)  # up to speed
    start = circle.pose
    period = 2 * math.pi / (0.2 / WHEEL_BASE)
    circle.advance(0.2 + period)
    assert (circle.pose.x, circle.pose.y) == pytest.approx((start.x, start.y), abs=1e-6)


def test_monitors_read_the_wheels_actual_speed() -> None:
    model = robot_model()
    body = CuboBody(model)
    body.apply(wheels(400, -900), 0.0)  # -900 is past the field's range: -500
    early = body.sensors(0.1)
    assert early["leftWheelMonitor"] == {"speed": 200}  # 2 m/s² for 0.1 s
    assert early["rightWheelMonitor"] == {"speed": -200}
    late = body.sensors(1.0)
    assert late["leftWheelMonitor"] == {"speed": 400}
    assert late["rightWheelMonitor"] == {"speed": -500}


def test_servos_move_at_a_bounded_rate() -> None:
    body = CuboBody(robot_model())
    body.apply({"leftArm": {"angle": 900}, "lip": {"opening": 100}}, 0.0)
    body.advance(0.1)
    assert body.actual("leftArm") == {"angle": round(RATES["leftArm"] * 0.1)}
    assert body.actual("lip") == {"opening": 50}
    body.advance(2.0)
    assert body.actual("leftArm") == {"angle": 900}
    assert body.actual("lip") == {"opening": 100}
    body.apply({"leftArm": {"angle": -900}}, 2.0)
    body.advance(2.5)
    assert body.actual("leftArm") == {"angle": 900 - 450}


def test_every_sensor_and_monitor_reads_values_the_robot_can_send() -> None:
    model = robot_model()
    body = CuboBody(model, seed=3)
    body.apply(wheels(250, 150), 10.0)
    readings = body.sensors(12.5)
    expected = {d.name for d in model.devices if d.kind in (DeviceKind.SENSOR, DeviceKind.MONITOR)}
    assert set(readings) == expected
    robot = RobotEndpoint(model)
    for name, values in readings.items():
        robot.set_state(name, values)  # encodes them: a value out of its field's range fails
    pose = body.pose
    assert readings["position"] == {"x": pose.x, "y": pose.y, "heading": pose.heading}
    samples = readings["microphone"]["samples"]
    assert isinstance(samples, bytes)
    assert len(samples) == 980


def test_the_battery_drains_faster_while_driving() -> None:
    model = robot_model()
    idle, driving = CuboBody(model), CuboBody(model)
    idle.advance(0.0)  # the first call sets a body's clock
    driving.apply(wheels(500, 500), 0.0)
    for body in (idle, driving):
        body.advance(600.0)
    assert 100 > idle.charge > driving.charge > 0
    assert idle.sensors(600.0)["battery"] == {"charge": round(idle.charge)}


def test_same_seed_same_readings_and_time_never_runs_backwards() -> None:
    model = robot_model()
    one, two, other = CuboBody(model, seed=7), CuboBody(model, seed=7), CuboBody(model, seed=8)
    for body in (one, two, other):
        body.apply(wheels(300, 280), 5.0)
    ticks = [5.0 + 0.02 * k for k in range(1, 200)]
    first = [one.sensors(t) for t in ticks]
    assert first == [two.sensors(t) for t in ticks]
    assert first != [other.sensors(t) for t in ticks]  # the noise differs
    picky = CuboBody(model, seed=7)  # measures two devices only: the same values
    picky.apply(wheels(300, 280), 5.0)
    only = [picky.sensors(t, ["position", "leftWheelMonitor"]) for t in ticks]
    assert only == [{n: v for n, v in f.items() if n in only[0]} for f in first]
    assert set(only[0]) == {"position", "leftWheelMonitor"}
    pose = one.pose
    one.advance(1.0)  # earlier than the body's clock: nothing moves
    assert one.pose == pose


def occurrences_over(body: CuboBody, start: float, seconds: float, tick: float = 0.02) -> list:
    """(time, device, values) of every occurrence, asked once a tick."""
    found = []
    body.occurrences(start)  # the first call sets the clock
    for k in range(1, round(seconds / tick) + 1):
        now = start + k * tick
        found += [(round(now, 6), name, dict(values)) for name, values in body.occurrences(now)]
    return found


def test_same_seed_same_occurrences_however_often_asked() -> None:
    model = robot_model()
    ticked = occurrences_over(CuboBody(model, seed=7), 5.0, 30.0)
    assert ticked == occurrences_over(CuboBody(model, seed=7), 5.0, 30.0)
    at_once = CuboBody(model, seed=7)
    at_once.occurrences(5.0)
    assert at_once.occurrences(35.0) == [(name, values) for _, name, values in ticked]
    assert ticked != occurrences_over(CuboBody(model, seed=8), 5.0, 30.0)
    # What is measured or driven, and when, changes nothing of them.
    busy = CuboBody(model, seed=7)
    busy.apply(wheels(300, -100), 5.0)
    for t in (6.0, 7.5, 9.0):
        busy.sensors(t)
    assert occurrences_over(busy, 9.0, 26.0) == [o for o in ticked if o[0] > 9.0 + 1e-9]
    later = occurrences_over(CuboBody(model, seed=7), 100.0, 30.0)  # timed from the first call
    assert [(round(t - 95.0, 6), n, v) for t, n, v in later] == ticked


def test_a_button_is_pressed_then_released_in_turn() -> None:
    found = occurrences_over(CuboBody(robot_model(), seed=3), 0.0, 60.0)
    for button in BUTTONS:
        pressed = [values[PRESSED] for _, name, values in found if name == button]
        assert len(pressed) > 20
        assert pressed == [index % 2 == 0 for index in range(len(pressed))]


def test_presses_and_dips_come_at_the_rates_given() -> None:
    model = robot_model()
    tick = 0.005  # occurrences are seen on the tick after they happen
    found = occurrences_over(CuboBody(model, seed=11), 0.0, 200.0, tick=tick)
    for button in BUTTONS:
        times = [t for t, name, _ in found if name == button]
        holds = [b - a for a, b in zip(times[0::2], times[1::2], strict=False)]
        cycles = [b - a for a, b in itertools.pairwise(times[0::2])]
        assert min(holds) >= PRESS_HOLD[0] - tick
        assert max(holds) <= PRESS_HOLD[1] + tick
        assert min(cycles) >= PRESS_GAP[0] + PRESS_HOLD[0] - tick
        assert max(cycles) <= PRESS_GAP[1] + PRESS_HOLD[1] + tick
        mean = sum(PRESS_GAP) / 2 + sum(PRESS_HOLD) / 2
        assert statistics.mean(cycles) == pytest.approx(mean, rel=0.1)  # about once a second
    dips = [(t, values) for t, name, values in found if name == LOW_BATTERY]
    gaps = [b - a for (a, _), (b, _) in itertools.pairwise(dips)]
    assert min(gaps) >= DIP_GAP[0] - tick
    assert max(gaps) <= DIP_GAP[1] + tick
    assert statistics.mean(gaps) == pytest.approx(sum(DIP_GAP) / 2, rel=0.1)
    charges = {values[CHARGE] for _, values in dips}
    assert min(charges) >= LOW_CHARGE - DIP_DEPTH
    assert max(charges) < LOW_CHARGE
    robot = RobotEndpoint(model)  # no session: nothing is reported, but the values are checked
    for _, name, values in found[:50]:
        assert robot.occur(name, values) is None


def test_the_battery_warns_once_when_it_runs_low() -> None:
    body = CuboBody(robot_model(), charge=LOW_CHARGE + 0.0001)
    assert body.occurrences(0.0) == []
    assert body.occurrences(0.02) == [(LOW_BATTERY, {CHARGE: LOW_CHARGE - 1})]  # no dip yet
    assert body.occurrences(0.04) == []


def test_a_generic_body_raises_nothing() -> None:
    body = GenericBody(robot_model(EVERY_KIND))
    assert body.occurrences(0.0) == []
    assert body.occurrences(100.0) == []


def test_the_speaker_plays_what_the_audio_processor_played_last() -> None:
    """D-RSP-22, D-RSP-23: fragments in order, a late one dropped; the speaker's actual state is
    the fragment played last, and a new session starts afresh."""
    model = robot_model()
    robot = ReferenceRobot(model, RobotSettings(port=0))
    body = robot.body
    assert isinstance(body, CuboBody)

    def hear(fragment: int) -> None:
        samples = f"fragment {fragment}".encode()
        robot._hear(events.StateReceived("speaker", {"fragment": fragment, "samples": samples}, 0))

    for step, (fragment, playing) in enumerate([(3, 3), (5, 5), (4, 5), (6, 6), (6, 6)]):
        hear(fragment)
        robot._control_tick(0.02 * step)
        assert body.actual("speaker") == {
            "fragment": playing,
            "samples": f"fragment {playing}".encode(),
        }
    counts = robot.audio["speaker"].counts
    assert (counts.played, counts.gaps, counts.late, counts.duplicates) == (3, 1, 1, 1)
    robot._forget()  # a session ends
    hear(0)
    robot._control_tick(0.2)
    assert body.actual("speaker") == {"fragment": 0, "samples": b"fragment 0"}
