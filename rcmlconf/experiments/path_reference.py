"""The reference path of experiment 2 (`path_following`): a WIDTH x HEIGHT rectangle with corners
rounded to RADIUS, centred on 0, as a closed polyline (for the controller) and as an exact
distance field (for the path error)."""

from __future__ import annotations

import math
from typing import Any, NamedTuple

from rcmlconf.reference.drivers.room import Pose

#: The reference path: a WIDTH x HEIGHT rectangle, corners rounded to RADIUS, centred on 0.
WIDTH, HEIGHT, RADIUS = 2.0, 1.0, 0.3


class Point(NamedTuple):
    x: float
    y: float


class ReferencePath:
    """A rounded rectangle, as a closed polyline for the controller and as a distance field for
    the error (exact)."""

    def __init__(
        self,
        width: float = WIDTH,
        height: float = HEIGHT,
        radius: float = RADIUS,
        step: float = 0.005,
    ) -> None:
        self.half_width, self.half_height, self.radius = width / 2, height / 2, radius
        a, b, r = self.half_width - radius, self.half_height - radius, radius
        # Counter-clockwise from the middle of the bottom edge, heading +x.
        pieces: list[tuple[str, Any]] = [
            ("line", ((0.0, -b - r), (a, -b - r))),
            ("arc", ((a, -b), -math.pi / 2)),
            ("line", ((a + r, -b), (a + r, b))),
            ("arc", ((a, b), 0.0)),
            ("line", ((a, b + r), (-a, b + r))),
            ("arc", ((-a, b), math.pi / 2)),
            ("line", ((-a - r, b), (-a - r, -b))),
            ("arc", ((-a, -b), math.pi)),
            ("line", ((-a, -b - r), (0.0, -b - r))),
        ]
        points: list[Point] = []
        for kind, spec in pieces:
            if kind == "line":
                (x0, y0), (x1, y1) = spec
                n = max(1, round(math.hypot(x1 - x0, y1 - y0) / step))
                points += [Point(x0 + (x1 - x0) * i / n, y0 + (y1 - y0) * i / n) for i in range(n)]
            else:
                (cx, cy), start = spec
                n = max(1, round(r * math.pi / 2 / step))
                points += [
                    Point(
                        cx + r * math.cos(start + math.pi / 2 * i / n),
                        cy + r * math.sin(start + math.pi / 2 * i / n),
                    )
                    for i in range(n)
                ]
        self.points = points
        self.arc = [0.0]
        for p, q in zip(points, points[1:] + points[:1], strict=True):
            self.arc.append(self.arc[-1] + math.hypot(q.x - p.x, q.y - p.y))
        self.length = self.arc[-1]
        self.step = self.length / len(points)

    @property
    def start(self) -> Pose:
        first = self.points[0]
        return Pose(first.x, first.y, 0.0)

    def point_at(self, s: float) -> Point:
        n = len(self.points)
        i = round(s / self.step) % n
        return self.points[i]

    def nearest(self, x: float, y: float, around: float, behind: float, ahead: float) -> float:
        """The arc length, within [around - behind, around + ahead], of the path point nearest
        (x, y) (unbounded: laps add up)."""
        first = math.floor((around - behind) / self.step)
        last = math.ceil((around + ahead) / self.step)
        n = len(self.points)
        best, best_i = math.inf, first
        for i in range(first, last + 1):
            p = self.points[i % n]
            d = (p.x - x) ** 2 + (p.y - y) ** 2
            if d < best:
                best, best_i = d, i
        return best_i * self.step

    def distance(self, x: float, y: float) -> float:
        """Exact distance from (x, y) to the path (the rounded box's distance field)."""
        r = self.radius
        qx = abs(x) - (self.half_width - r)
        qy = abs(y) - (self.half_height - r)
        outside = math.hypot(max(qx, 0.0), max(qy, 0.0)) + min(max(qx, qy), 0.0)
        return abs(outside - r)
