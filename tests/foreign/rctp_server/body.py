"""The simulated robot behind the RCML: every data node is a variable; the sensors move.

Writable nodes hold what was last written (RCML describes a robot as a tree of variables). The
read-only sensor nodes of robot.rcml change on their own, when they exist in the file served.
"""

from __future__ import annotations

import math
from typing import Any

from rcml import Node, Robot, to_float32


class Body:
    STEP = 0.1  # seconds between two steps of the simulation

    def __init__(self, robot: Robot, now: float) -> None:
        self.nodes = {p: n for p, n in robot.nodes.items() if n.kind == "data"}
        self.values: dict[str, Any] = {p: n.default() for p, n in self.nodes.items()}
        self.t0 = self._last = now
        self._set("/sensors/status/model", "Gardener G-2")
        self._set("/sensors/status/serial", bytes.fromhex("4732000117a5c3e7"))
        self._set("/pump/settings/label", "tomatoes")
        self._set("/panel/note", "hello")
        self._set("/panel/ratio", 0.5)

    def _set(self, path: str, value: Any) -> None:
        node = self.nodes.get(path)
        if node is None:
            return
        try:
            encoded = node.encode(value)
        except (TypeError, ValueError, OverflowError, AttributeError):
            return  # the node of this name has another type in this RCML
        if len(encoded) <= node.max_size() and node.in_range(value):
            self.values[path] = value

    def get(self, path: str) -> Any:
        return self.values[path]

    def put(self, node: Node, value: Any) -> None:
        self.values[node.path] = value

    def step(self, now: float) -> None:
        if now - self._last < self.STEP:
            return
        self._last = now
        t = now - self.t0
        self._set("/sensors/status/uptime", int(t))
        pump = self.values.get("/pump/settings/pressure")
        if isinstance(pump, float):
            enabled = self.values.get("/pump/settings/enabled", False)
            flow = self.values.get("/pump/settings/flow", 0)
            target = 3.0 * flow / 1200 if enabled and isinstance(flow, int) else 0.0
            moved = pump + (target - pump) * 0.3
            moved = target if abs(target - moved) < 0.01 else round(moved, 2)
            self._set("/pump/settings/pressure", to_float32(moved))
        joints = [self.values.get(f"/arm/joints/{j}", 0) for j in ("shoulder", "elbow", "gripper")]
        if all(isinstance(j, int) for j in joints):
            load = (abs(joints[0]) + abs(joints[1])) / 2100 + joints[2] / 200
            self._set("/arm/joints/load", round(load, 3))
        self._set("/sensors/imu/accel", (to_float32(0.05 * math.sin(t)), 0.0, to_float32(9.81)))
        self._set("/sensors/imu/temp", 215 + round(3 * math.sin(t / 30)))
        self._set(
            "/sensors/status/soil", tuple(500 + round(50 * math.sin(t / 20 + i)) for i in range(4))
        )
