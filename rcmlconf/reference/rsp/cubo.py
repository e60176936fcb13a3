"""A simulated CUBO (paper §IV, Fig. 9; D-RSP-8): the body the reference robot moves.

Pure: time comes in as `now` (any epoch: the first call sets the body's clock, and a `now` earlier
than one already seen moves nothing), and every bit of noise is a function of the seed, the
sensor and the 20 ms tick it is read in, so the same calls give the same readings.

- *Wheels*: `leftWheel` and `rightWheel` are speeds in mm/s; the body drives at m/s, each wheel
  reaching its target at a bounded acceleration (`WHEEL_ACCELERATION`), along the arcs of
  `room.drive` (differential drive, `room.WHEEL_BASE`). There are no walls: the floor is endless.
- *Positions*: the arms, the head tilt and the lips move toward their targets at a bounded rate
  (`RATES`), as servos do.
- *Monitors* read their effector's actual state (a wheel's actual speed, not its target).
- *Sensors*: `position` is the pose (x, y in metres, heading in radians); `battery` drains slowly,
  faster while the wheels turn; the others read plausible indoor values with a little noise
  (nothing near: the proximity sensors read their range, the floor is there, 300 lx, 23.5 °C,
  a quiet microphone).
- *Events* (`occurrences`): a person at the robot presses the service and message buttons, each
  now and then (`PRESS_GAP`) and for a moment (`PRESS_HOLD`): a press is the button's event with
  `pressed` true, the release one with `pressed` false. The battery raises `lowBattery` (a memory
  event) when its charge falls under `LOW_CHARGE`, and at each of its load dips (`DIP_GAP`, see
  there). Times are drawn from the seed, the device and the occurrence's number, counted from the
  body's first `now`: the same seed and calls give the same occurrences.

Any other model's devices are handled generically: an effector's actual state is what it was last
told, a sensor reads its fields' zero values.
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Collection, Mapping
from dataclasses import dataclass

from rcmlconf.reference.drivers.room import Pose, drive
from rcmlconf.rsp.model import Device, DeviceKind, Field, RobotModel
from rcmlconf.values import Kind, Scalar, Value

Values = Mapping[str, Value]

#: Where a body starts unless told: the origin, heading along +x.
ORIGIN = Pose(0.0, 0.0, 0.0)

#: The wheels' effectors and the field holding their speed (mm/s).
WHEELS = ("leftWheel", "rightWheel")
SPEED = "speed"
#: m/s²: a 2 kg robot's small motors reach 0.5 m/s in a quarter of a second.
WHEEL_ACCELERATION = 2.0
#: Servo rates, in the field's unit per second: arms 90°/s and the head 60°/s (tenths of a
#: degree), lips 500 %/s.
RATES: dict[str, float] = {"leftArm": 900.0, "rightArm": 900.0, "headTilt": 600.0, "lip": 500.0}
#: The longest integration step (seconds): speeds change within a step while accelerating.
STEP = 0.005
#: Battery drain in percent per second: at rest (about 2 hours), and per m/s of mean wheel speed.
DRAIN_IDLE = 100 / 7200
DRAIN_PER_SPEED = 0.05
#: Noise changes once a tick of this many seconds (the paper's T).
NOISE_TICK = 0.02
#: What the sensors read when nothing is near.
PROXIMITY_RANGE_MM = 1500
ILLUMINANCE_LX = 300
TEMPERATURE = 235  # 0.1 °C
#: 8-bit unsigned silence, and the microphone's noise around it.
SILENCE = 128
MIC_NOISE = 2
#: The microphone's fragments: 8-bit samples at 8 kHz.
MIC_RATE = 8000
#: The buttons a person presses (D-RSP-8's events) and their field. Seconds from a release to the
#: button's next press, and how long a press is held: each drawn uniformly between the bounds, so a
#: button is pressed about once a second, often enough for a test to see several presses.
BUTTONS = ("serviceButton", "messageButton")
PRESSED = "pressed"
PRESS_GAP = (0.3, 1.5)
PRESS_HOLD = (0.08, 0.3)
#: The battery's memory event and its field, and the charge (percent) under which it is low.
LOW_BATTERY = "lowBattery"
CHARGE = "charge"
LOW_CHARGE = 20
#: Seconds between two load dips of the battery (uniform). A real CUBO raises `lowBattery` once,
#: when the draining charge crosses `LOW_CHARGE` (two hours from full, and the simulated battery
#: does that too); a test cannot wait for it. A pack's voltage also sags under load peaks (the
#: wheels starting, the speaker), and a gauge that reads the charge from the voltage then reads it
#: low for a moment: each dip raises `lowBattery` with such a reading, `DIP_DEPTH` points or fewer
#: under `LOW_CHARGE` (never above the actual charge). Seeded like the noise, so deterministic; as
#: frequent as this so that a conformance case sees several in a few seconds.
DIP_GAP = (0.3, 1.2)
DIP_DEPTH = 10


class CuboBody:
    """CUBO's body on an endless floor, from `start_pose`.

    `apply` sets what the effectors are to do (the motion filter's output, D-RSP-20); `advance`
    moves the body on to `now`; `sensors` reads every sensor and monitor of the model."""

    def __init__(
        self,
        model: RobotModel,
        start_pose: Pose = ORIGIN,
        *,
        seed: int = 0,
        charge: float = 100.0,
    ) -> None:
        self.model = model
        self.seed = seed
        self.pose = start_pose
        #: Percent.
        self.charge = charge
        #: Metres driven (the mean of the wheels' paths).
        self.odometer = 0.0
        self._time: float | None = None
        self._effectors = [d for d in model.devices if d.kind is DeviceKind.EFFECTOR]
        self._reported = [
            d for d in model.devices if d.kind in (DeviceKind.SENSOR, DeviceKind.MONITOR)
        ]
        #: Each effector's actual state and its target, field by field.
        self._actual: dict[str, dict[str, Value]] = {
            d.name: {f.name: f.zero() for f in d.fields} for d in self._effectors
        }
        self._target: dict[str, dict[str, Value]] = {
            name: dict(values) for name, values in self._actual.items()
        }
        #: Wheel speeds in m/s, actual (float: the fields round).
        self._wheels = dict.fromkeys(WHEELS, 0.0)
        self._positions: dict[str, float] = {}
        for name in RATES:
            found = model.device(name)
            if found is not None and found.fields and _numeric(found.fields[0]):
                zero = found.fields[0].zero()
                assert isinstance(zero, int | float)
                self._positions[name] = float(zero)
        self._microphone: tuple[int, bytes] | None = None
        #: The body's first `now`: occurrences are timed from it.
        self._start: float | None = None
        #: Each source of occurrences: what it raises next and when (None before the first call).
        self._next: list[_Next] | None = None
        #: The charge was under LOW_CHARGE at the last call of `occurrences`.
        self._low = charge < LOW_CHARGE

    # -- the robot's calls ---------------------------------------------------------------------

    def apply(self, effectors: Mapping[str, Values], now: float) -> None:
        """What each effector is to do from `now` on, by device name (unknown names ignored)."""
        self.advance(now)
        for name, values in effectors.items():
            target = self._target.get(name)
            if target is None:
                continue
            found = self.model.device(name)
            assert found is not None
            for field in found.fields:
                if field.name in values:
                    target[field.name] = _clamp(field, values[field.name])
            if name not in self._wheels and name not in self._positions:
                self._actual[name] = dict(target)  # no dynamics: at once

    def advance(self, now: float) -> None:
        """Move on to `now`: the wheels accelerate and drive, the servos turn, the battery
        drains."""
        if self._time is None:
            self._time = self._start = now
            return
        while self._time < now:
            step = min(STEP, now - self._time)
            self._step(step)
            self._time = now if step == now - self._time else self._time + step

    def sensors(
        self, now: float, only: Collection[str] | None = None
    ) -> dict[str, dict[str, Value]]:
        """Each sensor's and monitor's value at `now` (after moving on to it), by device name:
        those named in `only`, or every one. Noise is a function of the tick, so what is not
        measured changes nothing of what is."""
        self.advance(now)
        tick = math.floor(now / NOISE_TICK)
        found: dict[str, dict[str, Value]] = {}
        for device in self._reported:
            if only is not None and device.name not in only:
                continue
            if device.kind is DeviceKind.MONITOR:
                assert device.of is not None
                found[device.name] = self.actual(device.of)
            else:
                found[device.name] = self._sensor(device, tick, now)
        return found

    def occurrences(self, now: float) -> list[tuple[str, Values]]:
        """The button presses and releases and the low-battery warnings from the last call (the
        first call: from the body's first `now`) to `now`, oldest first, by device name. Each is
        a function of the seed and its number: what is asked when changes nothing of them."""
        self.advance(now)
        if self._next is None:
            assert self._start is not None
            self._next = self._sources(self._start)
        found: list[tuple[float, str, Values]] = []
        for source in self._next:
            while source.at <= now:
                found.append((source.at, source.device.name, self._raise(source)))
                source.index += 1
                source.at += self._gap(source)
        low = self.charge < LOW_CHARGE
        battery = self.model.device(LOW_BATTERY)
        if low and not self._low and _raises(battery, DeviceKind.MEMORY_EVENT, CHARGE):
            assert battery is not None
            found.append((now, LOW_BATTERY, self._values(battery, math.floor(self.charge))))
        self._low = low
        found.sort(key=lambda item: item[0])
        return [(name, values) for _, name, values in found]

    def actual(self, effector: str) -> dict[str, Value]:
        """An effector's actual state, as its fields hold it."""
        values = dict(self._actual[effector])
        found = self.model.device(effector)
        assert found is not None
        if effector in self._wheels and found.fields:
            values[SPEED] = _clamp(found.fields[0], self._wheels[effector] * 1000)
        elif effector in self._positions and found.fields:
            values[found.fields[0].name] = _clamp(found.fields[0], self._positions[effector])
        return values

    @property
    def wheel_speeds(self) -> tuple[float, float]:
        """The wheels' actual speeds, m/s."""
        return self._wheels[WHEELS[0]], self._wheels[WHEELS[1]]

    # -- moving --------------------------------------------------------------------------------

    def _step(self, elapsed: float) -> None:
        before = self.wheel_speeds
        change = WHEEL_ACCELERATION * elapsed
        for wheel in WHEELS:
            target = self._target.get(wheel, {}).get(SPEED, 0)
            goal = float(target) / 1000 if isinstance(target, int | float) else 0.0
            speed = self._wheels[wheel]
            self._wheels[wheel] = speed + max(-change, min(change, goal - speed))
        after = self.wheel_speeds
        # Speeds change linearly within the step: their means drive it (exact at constant speed).
        left, right = (before[0] + after[0]) / 2, (before[1] + after[1]) / 2
        if left or right:
            self.pose = drive(self.pose, left, right, elapsed)
        mean = abs(left + right) / 2
        self.odometer += mean * elapsed
        self.charge = max(0.0, self.charge - (DRAIN_IDLE + DRAIN_PER_SPEED * mean) * elapsed)
        for name, position in self._positions.items():
            target = self._target[name][self.model.by_name[name].fields[0].name]
            assert isinstance(target, int | float)
            move = RATES[name] * elapsed
            self._positions[name] = position + max(-move, min(move, float(target) - position))

    # -- occurrences ---------------------------------------------------------------------------

    def _sources(self, start: float) -> list[_Next]:
        """The buttons and the battery's dips the model has, each due at its first time."""
        sources = []
        for name in BUTTONS:
            button = self.model.device(name)
            if _raises(button, DeviceKind.EVENT, PRESSED):
                assert button is not None
                sources.append(_Next(button, start))
        battery = self.model.device(LOW_BATTERY)
        if _raises(battery, DeviceKind.MEMORY_EVENT, CHARGE):
            assert battery is not None
            sources.append(_Next(battery, start))
        for source in sources:
            source.at += self._gap(source)
        return sources

    def _gap(self, source: _Next) -> float:
        """Seconds from occurrence `source.index - 1` to occurrence `source.index` (from the start
        to the first): a button's releases (odd numbers) come a hold after their press, its
        presses a gap after the release before."""
        if source.device.kind is DeviceKind.MEMORY_EVENT:
            low, high = DIP_GAP
        else:
            low, high = PRESS_HOLD if source.index % 2 else PRESS_GAP
        return low + (high - low) * self._draw(source.device.name, source.index)

    def _raise(self, source: _Next) -> dict[str, Value]:
        """The values of occurrence `source.index`: a press or a release, or a dip's reading."""
        if source.device.kind is DeviceKind.EVENT:
            return self._values(source.device, source.index % 2 == 0)
        depth = 1 + math.floor(DIP_DEPTH * self._draw(source.device.name, source.index, "depth"))
        return self._values(source.device, min(LOW_CHARGE - depth, math.floor(self.charge)))

    @staticmethod
    def _values(device: Device, value: Value) -> dict[str, Value]:
        """The device's fields at their safe values, its first field `value`."""
        values: dict[str, Value] = {f.name: f.zero() for f in device.fields}
        values[device.fields[0].name] = _clamp(device.fields[0], value)
        return values

    def _draw(self, name: str, index: int, what: str = "gap") -> float:
        """A number in [0, 1) fixed by the seed, the device, the occurrence and `what`."""
        digest = hashlib.blake2b(
            f"{self.seed}/{name}/{what}/{index}".encode(), digest_size=8
        ).digest()
        return int.from_bytes(digest) / 2**64

    # -- sensing -------------------------------------------------------------------------------

    def _sensor(self, device: Device, tick: int, now: float) -> dict[str, Value]:
        name = device.name
        fields = {f.name: f for f in device.fields}
        values: dict[str, Value] = {f.name: f.zero() for f in device.fields}
        pose = self.pose
        readings: dict[str, Value]
        if name == "position":
            readings = {"x": pose.x, "y": pose.y, "heading": pose.heading}
        elif name == "battery":
            readings = {"charge": round(self.charge)}
        elif name == "proximity":
            count = fields["distance"].type.count if "distance" in fields else 1
            readings = {
                "distance": tuple(
                    PROXIMITY_RANGE_MM - round(5 * abs(self._noise(name, tick, i)))
                    for i in range(count)
                )
            }
        elif name == "floor":
            count = fields["drop"].type.count if "drop" in fields else 1
            readings = {"drop": tuple([False] * count)}
        elif name == "luminance":
            readings = {"illuminance": ILLUMINANCE_LX + round(10 * self._noise(name, tick))}
        elif name == "temperature":
            readings = {"temperature": TEMPERATURE + round(2 * self._noise(name, tick))}
        elif name == "microphone":
            readings = self._listen(fields, now)
        else:
            readings = {}
        for key, value in readings.items():
            field = fields.get(key)
            if field is not None:
                values[key] = _clamp(field, value)
        return values

    def _listen(self, fields: Mapping[str, Field], now: float) -> dict[str, Value]:
        """The microphone's newest whole fragment: quiet noise around silence."""
        samples = fields.get("samples")
        size = samples.type.size if samples is not None else 0
        if not size:
            return {}
        fragment = max(math.floor(now * MIC_RATE / size) - 1, 0) % 65536
        if self._microphone is None or self._microphone[0] != fragment:
            stream = hashlib.shake_128(f"{self.seed}/microphone/{fragment}".encode()).digest(size)
            noise = bytes(SILENCE + b % (2 * MIC_NOISE + 1) - MIC_NOISE for b in stream)
            self._microphone = (fragment, noise)
        return {"fragment": fragment, "samples": self._microphone[1]}

    def _noise(self, name: str, tick: int, index: int = 0) -> float:
        """A number in [-1, 1) fixed by the seed, the sensor, its item and the tick."""
        digest = hashlib.blake2b(
            f"{self.seed}/{name}/{index}/{tick}".encode(), digest_size=8
        ).digest()
        return int.from_bytes(digest) / 2**63 - 1.0


@dataclass(slots=True)
class _Next:
    """A source of occurrences: a button or the battery, its next occurrence's number and time."""

    device: Device
    at: float
    index: int = 0


def _raises(device: Device | None, kind: DeviceKind, field: str) -> bool:
    """`device` is of `kind` and its first field is `field` (CUBO's, not another model's)."""
    return (
        device is not None
        and device.kind is kind
        and bool(device.fields)
        and device.fields[0].name == field
    )


def _numeric(field: Field) -> bool:
    return field.type.base.numeric and not field.type.is_array


def _clamp(field: Field, value: Value) -> Value:
    """`value` as the field holds it: within its range, integers rounded, floats as float32."""
    if isinstance(value, tuple):
        return tuple(_clamp_one(field, item) for item in value)
    return _clamp_one(field, value)


def _clamp_one(field: Field, item: Scalar) -> Scalar:
    kind = field.type.base.kind
    if isinstance(item, bool) or not isinstance(item, int | float):
        return item
    if kind is Kind.INTEGER:
        low = field.minimum if field.minimum is not None else field.type.base.low
        high = field.maximum if field.maximum is not None else field.type.base.high
        return int(min(max(round(item), low), high))
    if kind is Kind.FLOAT:
        value = float(item)
        if field.minimum is not None:
            value = max(value, float(field.minimum))
        if field.maximum is not None:
            value = min(value, float(field.maximum))
        return value
    return item
