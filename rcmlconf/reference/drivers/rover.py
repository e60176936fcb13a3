"""`rover`: the two-wheeled robot of robots/rover/rover.rcml, driving in a 4 m square room.

The robot's footprint is a square whose corners lie `BODY_RADIUS` from its centre, at ±45° and
±135° from the heading; the front two carry the bumpers. A corner comes no nearer a wall than
`CONTACT`: a move that would take a corner closer than that, and closer than it was, stops at the
moment of contact (found by bisection), and a bumper whose corner touches is pressed. The robot
then stays against the wall until it is told to move away.

Wheel commands are limited, not refused: in mode 2 both speeds are halved, in mode 0 they are
ignored, and when the faster wheel exceeds `maxSpeed` both are scaled down alike, so the robot
keeps the curve it was told to drive. The wheels read the speeds the robot drives at.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

from rcmlconf.rcml.model import Permission
from rcmlconf.reference.drivers.nodes import Need, number
from rcmlconf.reference.drivers.room import Pose, clearance, drive, ray
from rcmlconf.reference.drivers.simulated import SimulatedRobot
from rcmlconf.values import Kind, Value

LEFT, RIGHT = "/drive/wheels/left", "/drive/wheels/right"
MAX_SPEED, MODE = "/drive/settings/maxSpeed", "/drive/settings/mode"
POSE, RANGE = "/sensors/odometry/pose", "/sensors/odometry/range"
BUMPER_LEFT, BUMPER_RIGHT = "/sensors/events/bumperLeft", "/sensors/events/bumperRight"
BATTERY = "/sensors/events/battery"
NAME, SERIAL = "/identity/info/name", "/identity/info/serial"

_RW = Permission.READ | Permission.WRITE

#: Settings when the robot starts: mode 1 drives at the speeds written.
DEFAULT_MAX_SPEED = 0.5
DEFAULT_MODE = 1
#: Mode -> factor on the wheel speeds written (a mode the model allows beyond 2 drives as 1).
MODE_FACTORS = {0: 0.0, 1: 1.0, 2: 0.5}
SERIAL_NUMBER = 20260001

BODY_RADIUS = 0.15
CORNERS = tuple(math.radians(a) for a in (45, -45, 135, -135))
FRONT_LEFT, FRONT_RIGHT = CORNERS[:2]
#: Closest a corner comes to a wall; a bumper within CONTACT + CONTACT_SLACK is pressed (the
#: bisection stops a hair short of CONTACT).
CONTACT = 0.18
CONTACT_SLACK = 1e-3
BISECTIONS = 24

#: Infrared sensors on the rim, left of the heading; what they see, in millimetres.
SENSOR_BEARINGS = tuple(math.radians(a) for a in (-75, -45, -15, 15, 45, 75))
RANGE_CAP_MM = 2000

#: Integration step, and the most steps one call takes: a jump of over STEP * MAX_STEPS seconds
#: takes longer steps, whose arcs may cut a corner of the room but never end outside it.
STEP = 0.01
MAX_STEPS = 1000

#: Battery drain in percent per second: at rest, and per m/s of mean wheel speed.
DRAIN_IDLE = 0.001
DRAIN_PER_SPEED = 0.01
#: The battery reads in steps of this many percent, so its events are not a stream.
BATTERY_RESOLUTION = 0.1


class RoverDriver(SimulatedRobot):
    name = "rover"
    needs = (
        Need(LEFT, Kind.FLOAT, _RW),
        Need(RIGHT, Kind.FLOAT, _RW),
        Need(MAX_SPEED, Kind.FLOAT, _RW),
        Need(MODE, Kind.INTEGER, _RW),
        Need(POSE, Kind.FLOAT, count=3),
        Need(RANGE, Kind.INTEGER, count=len(SENSOR_BEARINGS)),
        Need(BUMPER_LEFT, Kind.BOOL),
        Need(BUMPER_RIGHT, Kind.BOOL),
        Need(BATTERY, Kind.FLOAT),
        Need(NAME, Kind.STRING),
        Need(SERIAL, Kind.INTEGER),
    )

    def _begin(self) -> None:
        self._pose = Pose(0.0, 0.0, 0.0)
        self._battery = 100.0
        #: The wheel speeds last written (or zero, since mode 0).
        self._wanted = (0.0, 0.0)
        self._set_numbers(MAX_SPEED, DEFAULT_MAX_SPEED)
        self._set_numbers(MODE, DEFAULT_MODE)
        self._set_text(NAME, "rover")
        self._set_numbers(SERIAL, SERIAL_NUMBER)
        self._limit()
        self._sense()

    def _write(self, values: Mapping[str, Value]) -> None:
        # Settings first, so that a command changing the mode and the wheels together drives
        # (or stops) as the new mode says.
        super()._write({path: v for path, v in values.items() if path not in (LEFT, RIGHT)})
        if self._setting(MODE) == 0:
            self._wanted = (0.0, 0.0)
        else:
            left, right = (
                _finite(number(values[path])) if path in values else wanted
                for path, wanted in zip((LEFT, RIGHT), self._wanted, strict=True)
            )
            self._wanted = (left, right)
        self._limit()

    def _simulate(self, elapsed: float) -> None:
        left, right = self._speeds
        if left or right:
            steps = min(MAX_STEPS, math.ceil(elapsed / STEP))
            for _ in range(steps):
                if not self._step(left, right, elapsed / steps):
                    break  # against a wall: every later step would be refused as well
        drain = DRAIN_IDLE + DRAIN_PER_SPEED * (abs(left) + abs(right)) / 2
        self._battery = max(0.0, self._battery - drain * elapsed)
        self._sense()

    def _setting(self, path: str) -> float:
        return _finite(number(self._values[path]))

    def _limit(self) -> None:
        """Set the wheels to the speeds written, as the mode and `maxSpeed` allow."""
        left, right = self._wanted
        factor = MODE_FACTORS.get(int(self._setting(MODE)), 1.0)
        fastest = max(abs(left), abs(right))
        limit = max(0.0, self._setting(MAX_SPEED))
        scale = factor * min(1.0, limit / fastest) if fastest else 0.0
        self._set_numbers(LEFT, left * scale)
        self._set_numbers(RIGHT, right * scale)
        # Drive at exactly the speeds the wheels read (float32, within the nodes' ranges).
        self._speeds = (number(self._values[LEFT]), number(self._values[RIGHT]))

    def _step(self, left: float, right: float, elapsed: float) -> bool:
        """Drive for `elapsed` seconds; False when a corner met a wall and the robot stopped."""
        start = self._pose
        before = [clearance(*start.point(BODY_RADIUS, corner)) for corner in CORNERS]

        def blocked(fraction: float) -> bool:
            pose = drive(start, left, right, elapsed * fraction)
            return any(
                (after := clearance(*pose.point(BODY_RADIUS, corner))) < CONTACT and after < old
                for corner, old in zip(CORNERS, before, strict=True)
            )

        if not blocked(1.0):
            self._pose = drive(start, left, right, elapsed)
            return True
        free, stuck = 0.0, 1.0
        for _ in range(BISECTIONS):
            middle = (free + stuck) / 2
            free, stuck = (free, middle) if blocked(middle) else (middle, stuck)
        self._pose = drive(start, left, right, elapsed * free)
        return False

    def _sense(self) -> None:
        pose = self._pose
        self._set_numbers(POSE, *pose)
        self._set_numbers(
            RANGE,
            *(
                min(RANGE_CAP_MM, (ray(pose.x, pose.y, pose.heading + b) - BODY_RADIUS) * 1000)
                for b in SENSOR_BEARINGS
            ),
        )
        for path, corner in ((BUMPER_LEFT, FRONT_LEFT), (BUMPER_RIGHT, FRONT_RIGHT)):
            self._set(path, clearance(*pose.point(BODY_RADIUS, corner)) <= CONTACT + CONTACT_SLACK)
        steps = round(self._battery / BATTERY_RESOLUTION)
        self._set_numbers(BATTERY, steps * BATTERY_RESOLUTION)


def _finite(speed: float) -> float:
    """A written NaN (which no `min`/`max` keeps out, D-RCML-12) or infinity stops the robot
    rather than poisoning its pose."""
    return speed if math.isfinite(speed) else 0.0
