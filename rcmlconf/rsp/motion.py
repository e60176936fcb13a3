"""The robot's motion filter (D-RSP-20, paper Fig. 5), without I/O: what the effectors get.

Effector values reach the robot late, bunched or not at all. The filter turns what arrived into
what the effectors get at any moment (`output(now)`):
- *hold*: nothing new, the last value stays (R-RSP-34);
- *collapse*: of values that arrive within one control period only the newest counts, since
  `output` is asked once a period and only the newest target is kept (R-RSP-34);
- *interpolate*: a value after lost packets (its timestamp more than 1.5 periods after the last
  one's) is reached in a straight line over one period, numeric fields only (R-RSP-35);
- *stop*: while the link is lost, `onLoss="zero"` effectors go to their zero (R-RSP-36).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from rcmlconf.rsp.model import Device, DeviceKind, Field, OnLoss, RobotModel
from rcmlconf.values import Kind, Scalar, Value

#: D-RSP-20: a gap in timestamps longer than this many periods means packets were lost.
GAP_PERIODS = 1.5


@dataclass(slots=True)
class _Effector:
    device: Device
    #: The newest value received, and its packet's timestamp (milliseconds).
    target: dict[str, Value]
    stamp: int | None = None
    #: A ramp from `start` toward `target` over one period, from `ramp_from` (seconds).
    start: dict[str, Value] | None = None
    ramp_from: float = 0.0
    #: Every field numeric: only such an effector is interpolated (D-RSP-20); an LCD's picture or
    #: a speaker's fragment (D-RSP-22) is taken whole.
    numeric: bool = True


def _between(field: Field, start: Value, end: Value, share: float) -> Value:
    """A numeric field `share` of the way from `start` to `end` (integers rounded)."""
    if not field.type.base.numeric:
        return end
    integer = field.type.base.kind is Kind.INTEGER

    def one(a: Scalar, b: Scalar) -> Scalar:
        assert isinstance(a, int | float)
        assert isinstance(b, int | float)
        value = a + (b - a) * share
        return round(value) if integer else value

    if isinstance(start, tuple) and isinstance(end, tuple):
        return tuple(one(a, b) for a, b in zip(start, end, strict=True))
    assert not isinstance(start, tuple)
    assert not isinstance(end, tuple)
    return one(start, end)


class MotionFilter:
    __slots__ = ("_effectors", "link_lost", "period")

    def __init__(self, model: RobotModel, period: float) -> None:
        self.period = period
        self._effectors = {
            d.position: _Effector(
                d,
                {f.name: f.zero() for f in d.fields},
                numeric=all(f.type.base.numeric for f in d.fields),
            )
            for d in model.devices
            if d.kind is DeviceKind.EFFECTOR
        }
        self.link_lost = False

    def lose_link(self) -> None:
        """Nothing from the local system for 25 periods (D-RSP-13): `onLoss="zero"` effectors
        stop, and stay stopped until a new value comes (a wheel must not resume an old speed)."""
        self.link_lost = True
        for effector in self._effectors.values():
            if effector.device.on_loss is OnLoss.ZERO:
                effector.target = {f.name: f.zero() for f in effector.device.fields}
                effector.start = None

    def receive(self, device: Device, values: Mapping[str, Value], stamp: int, now: float) -> None:
        """A newer packet's value of an effector (the session judged it newer, D-RSP-15);
        `stamp` is the packet's timestamp in milliseconds. A value means the link is back."""
        self.link_lost = False
        effector = self._effectors[device.position]
        late = (
            effector.stamp is not None
            and effector.numeric
            and ((stamp - effector.stamp) % (1 << 32)) > GAP_PERIODS * self.period * 1000
        )
        effector.start = self._now(effector, now) if late else None
        effector.ramp_from = now
        effector.target = dict(values)
        effector.stamp = stamp

    def output(self, now: float) -> dict[str, dict[str, Value]]:
        """Every effector's values to apply now, by device name."""
        # Most hold their target, no ramp running (R-RSP-34): that one without a call.
        return {
            e.device.name: e.target if e.start is None else self._now(e, now)
            for e in self._effectors.values()
        }

    def _now(self, effector: _Effector, now: float) -> dict[str, Value]:
        start = effector.start
        if start is None:
            return effector.target
        share = (now - effector.ramp_from) / self.period
        if share >= 1:
            effector.start = None
            return effector.target
        return {
            f.name: _between(f, start[f.name], effector.target[f.name], max(share, 0.0))
            for f in effector.device.fields
        }
