"""The local system's controller in experiment 2 (`path_following`): pure pursuit of the
reference path, fed only by the positions it receives.

Every T the controller takes the newest position, finds the path point `LOOKAHEAD` ahead of the
nearest one, and sets the wheel speeds of the arc through it at `SPEED`; after one lap (by its
own reckoning) it stops the wheels.
"""

from __future__ import annotations

import math

from rcmlconf.experiments.path_reference import ReferencePath
from rcmlconf.reference.drivers.room import WHEEL_BASE, Pose

#: The controller: cruising speed (m/s), look-ahead (m), the wheels' limit (m/s, CUBO's 500 mm/s).
SPEED = 0.25
LOOKAHEAD = 0.3
MAX_WHEEL = 0.5


class PurePursuit:
    """The local system's controller (module docstring)."""

    def __init__(
        self,
        path: ReferencePath,
        speed: float = SPEED,
        lookahead: float = LOOKAHEAD,
        max_wheel: float = MAX_WHEEL,
    ) -> None:
        self.path = path
        self.speed = speed
        self.lookahead = lookahead
        self.max_wheel = max_wheel
        self.progress = 0.0
        self.done = False

    def command(self, pose: Pose | None) -> tuple[float, float]:
        """Wheel speeds (m/s) for the newest pose known; none known, or the lap done: stop."""
        if pose is None or self.done:
            return 0.0, 0.0
        path = self.path
        found = path.nearest(pose.x, pose.y, self.progress, 0.1, 0.5)
        self.progress = max(self.progress, found)
        if self.progress >= path.length:
            self.done = True
            return 0.0, 0.0
        target = path.point_at(min(self.progress + self.lookahead, path.length))
        dx, dy = target.x - pose.x, target.y - pose.y
        cos, sin = math.cos(pose.heading), math.sin(pose.heading)
        ahead, left = cos * dx + sin * dy, -sin * dx + cos * dy
        reach = max(ahead * ahead + left * left, 1e-9)
        curvature = 2 * left / reach  # the arc through the target, tangent to the heading
        turn = self.speed * curvature * WHEEL_BASE / 2
        wheels = (self.speed - turn, self.speed + turn)
        fastest = max(abs(wheels[0]), abs(wheels[1]))
        scale = min(1.0, self.max_wheel / fastest) if fastest else 1.0
        return wheels[0] * scale, wheels[1] * scale
