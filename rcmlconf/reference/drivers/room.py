"""The rover's world: a differential-drive body in a square room, as plain geometry.

Coordinates are metres, angles radians counter-clockwise, heading 0 along +x. The room is 4 m by
4 m, centred on the origin.
"""

from __future__ import annotations

import math
from typing import NamedTuple

#: Half the side of the room: the walls are at x = ±HALF_ROOM and y = ±HALF_ROOM.
HALF_ROOM = 2.0
#: Distance between the wheels.
WHEEL_BASE = 0.3


class Pose(NamedTuple):
    x: float
    y: float
    #: Within [-pi, pi].
    heading: float

    def point(self, reach: float, bearing: float) -> tuple[float, float]:
        """The point `reach` metres from the centre, `bearing` radians left of the heading."""
        angle = self.heading + bearing
        return self.x + reach * math.cos(angle), self.y + reach * math.sin(angle)


def drive(pose: Pose, left: float, right: float, elapsed: float) -> Pose:
    """Where the wheel speeds (m/s) take `pose` in `elapsed` seconds: exactly, along the arc
    that constant speeds draw, so a step may be long."""
    speed = (left + right) / 2
    turn = (right - left) / WHEEL_BASE
    if abs(turn * elapsed) < 1e-12:  # straight on (the arc's radius is infinite)
        x = pose.x + speed * elapsed * math.cos(pose.heading)
        y = pose.y + speed * elapsed * math.sin(pose.heading)
        return Pose(x, y, pose.heading)
    heading = pose.heading + turn * elapsed
    radius = speed / turn
    x = pose.x + radius * (math.sin(heading) - math.sin(pose.heading))
    y = pose.y - radius * (math.cos(heading) - math.cos(pose.heading))
    return Pose(x, y, math.remainder(heading, math.tau))


def clearance(x: float, y: float) -> float:
    """Distance from a point in the room to the nearest wall (negative outside)."""
    return HALF_ROOM - max(abs(x), abs(y))


def ray(x: float, y: float, angle: float) -> float:
    """Distance from a point in the room to the wall straight ahead in direction `angle`."""
    dx, dy = math.cos(angle), math.sin(angle)
    hits = [
        (math.copysign(HALF_ROOM, d) - start) / d
        for start, d in ((x, dx), (y, dy))
        if abs(d) > 1e-12
    ]
    return min(hits)
