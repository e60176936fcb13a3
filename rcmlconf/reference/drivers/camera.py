"""`camera`: the pan/tilt/zoom/focus camera of the RCML 2.0 paper (robots/camera/camera.rcml).

A written axis value is a set point; the value read is where the axis is, moving toward the set
point at a motor's pace. `moving` tells whether any axis is still on its way.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

from rcmlconf.rcml.model import Permission
from rcmlconf.reference.drivers.nodes import Need, number
from rcmlconf.reference.drivers.simulated import SimulatedRobot
from rcmlconf.values import Kind, Value

#: Axis -> speed toward its set point, in its unit (degrees, percent) per second.
RATES = {
    "/stream/control/pan": 60.0,
    "/stream/control/tilt": 60.0,
    "/stream/control/zoom": 50.0,
    "/stream/control/focus": 50.0,
}
MOVING = "/status/lens/moving"
MODEL = "/status/lens/model"
MODEL_NAME = "rcmlconf PTZ-1 (simulated)"


class CameraDriver(SimulatedRobot):
    name = "camera"
    needs = (
        *(Need(path, Kind.INTEGER, Permission.READ | Permission.WRITE) for path in RATES),
        Need(MOVING, Kind.BOOL),
        Need(MODEL, Kind.STRING),
    )

    def _begin(self) -> None:
        self._position = {path: number(self._values[path]) for path in RATES}
        self._target = dict(self._position)
        self._set_text(MODEL, MODEL_NAME)

    def _write(self, values: Mapping[str, Value]) -> None:
        for path in RATES.keys() & values.keys():
            self._target[path] = number(values[path])
        super()._write({path: v for path, v in values.items() if path not in RATES})
        self._set(MOVING, self._position != self._target)

    def _simulate(self, elapsed: float) -> None:
        for path, rate in RATES.items():
            position, target = self._position[path], self._target[path]
            step = rate * elapsed
            if abs(target - position) <= step:
                position = target
            else:
                position += math.copysign(step, target - position)
            self._position[path] = position
            self._set_numbers(path, position)
        self._set(MOVING, self._position != self._target)
