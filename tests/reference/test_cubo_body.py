"""The simulated CUBO (rcmlconf.reference.rsp.cubo): kinematics, servos, sensors, determinism."""

from __future__ import annotations

import math

import pytest
from support.rsp_models import robot_model

from rcmlconf.reference.drivers.room import WHEEL_BASE, Pose
from rcmlconf.reference.rsp.cubo import RATES, WHEEL_ACCELERATION, CuboBody
from rcmlconf.rsp.model import DeviceKind
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
