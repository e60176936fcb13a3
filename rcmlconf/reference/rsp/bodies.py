"""What the reference robot moves: a body that takes effector values, reports its sensors and
monitors, and raises its events and memory events. CUBO (D-RSP-8) has a simulated body of its own
(`cubo`); any other model gets a generic one. Bodies are pure: time comes in as `now`."""

from __future__ import annotations

from collections.abc import Collection, Mapping
from typing import Protocol

from rcmlconf.rsp.model import DeviceKind, RobotModel
from rcmlconf.values import Value

Values = Mapping[str, Value]


class Body(Protocol):
    def apply(self, effectors: Mapping[str, Values], now: float) -> None:
        """What each effector is to do now (the motion filter's output, D-RSP-20)."""

    def advance(self, now: float) -> None:
        """Move on to `now`."""

    def sensors(self, now: float, only: Collection[str] | None = None) -> Mapping[str, Values]:
        """Each sensor's and monitor's value now, by device name: those named in `only`, or
        every one."""

    def occurrences(self, now: float) -> list[tuple[str, Values]]:
        """The events and memory events that happened since the last call, oldest first, as
        (device name, values): what the robot raises (`RobotEndpoint.occur`)."""


class GenericBody:
    """Any model: effectors do at once what they are told, monitors say so, sensors read their
    fields' zero values (D-RSP-20's safe state), and nothing happens: no event is raised."""

    __slots__ = ("_effectors", "_monitors", "_names", "_sensors")

    def __init__(self, model: RobotModel) -> None:
        self._monitors = {d.name: d.of for d in model.devices if d.kind is DeviceKind.MONITOR}
        self._sensors = {
            d.name: {f.name: f.zero() for f in d.fields}
            for d in model.devices
            if d.kind is DeviceKind.SENSOR
        }
        self._effectors: dict[str, Values] = {}
        self._names = [*self._sensors, *self._monitors]

    def apply(self, effectors: Mapping[str, Values], now: float) -> None:
        self._effectors = dict(effectors)

    def advance(self, now: float) -> None:
        pass

    def sensors(self, now: float, only: Collection[str] | None = None) -> Mapping[str, Values]:
        # Only those asked for: a robot asks each tick for what the next UPLINK carries, a few
        # of all (D-RSP-14).
        sensors, monitors, effectors = self._sensors, self._monitors, self._effectors
        found: dict[str, Values] = {}
        for name in self._names if only is None else only:
            if name in sensors:
                found[name] = sensors[name]
            else:
                effector = monitors.get(name)
                if effector is not None and effector in effectors:
                    found[name] = effectors[effector]
        return found

    def occurrences(self, now: float) -> list[tuple[str, Values]]:
        return []


def body_for(model: RobotModel, seed: int) -> Body:
    """CUBO's simulated body for the CUBO model, a generic one for any other."""
    if model.name == "CUBO":
        from rcmlconf.reference.rsp.cubo import CuboBody

        return CuboBody(model, seed=seed)
    return GenericBody(model)
