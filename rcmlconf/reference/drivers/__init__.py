"""Robot drivers: what the reference server controls (issue 5).

A driver owns the values of a robot's data nodes. The server asks it for values, hands it the
values clients write (already checked for type, range, permission and privilege), and lets it move
to the present so that streams and events carry real changes. Simulated robots ship as examples;
a real robot is one more class with these four methods, registered in `DRIVERS` with the
classmethods `fits` and `mismatch` that `DriverClass` asks for.

Drivers are pure: time comes in as `now` (seconds, any epoch), randomness from the seed given to
`start`, so a run is repeatable and a test can step a driver by hand.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Protocol

from rcmlconf.errors import RcmlconfError
from rcmlconf.rcml.model import RcmlDocument
from rcmlconf.reference.drivers.camera import CameraDriver
from rcmlconf.reference.drivers.rover import RoverDriver
from rcmlconf.reference.drivers.simulated import SimulatedRobot
from rcmlconf.values import Value


class Driver(Protocol):
    #: The name `--driver` selects it by.
    name: str

    def start(self, model: RcmlDocument, now: float, seed: int) -> None:
        """Take the robot: every data node of `model` gets its first value."""

    def values(self) -> Mapping[str, Value]:
        """The value of every data node, by path (D-RCML-3); the server reads it, never writes."""

    def advance(self, now: float) -> Iterable[str]:
        """Move the robot to `now` (never earlier than the last `now`); the paths that changed."""

    def command(self, values: Mapping[str, Value], now: float) -> Iterable[str]:
        """Apply written values, all together (R-RCTP-29); the paths whose values changed."""


class DriverClass(Protocol):
    """A driver's class, as the registry holds it: made without arguments, and able to say
    whether it can drive a model."""

    def __call__(self) -> Driver: ...

    def fits(self, model: RcmlDocument) -> bool: ...

    def mismatch(self, model: RcmlDocument) -> str | None:
        """Why it cannot drive `model` (a node it needs is missing or unlike), or None."""


class DriverError(RcmlconfError):
    """No driver of that name, or one that cannot drive the robot's model."""


#: Name -> driver; `auto` tries the specialised ones in this order.
DRIVERS: dict[str, DriverClass] = {
    cls.name: cls for cls in (CameraDriver, RoverDriver, SimulatedRobot)
}
AUTO = "auto"


def choose_driver(name: str, model: RcmlDocument) -> Driver:
    """The driver `--driver NAME` selects for `model`, not yet started.

    `auto` picks the first specialised driver that fits the model, else `sim`, which fits any.
    """
    if name == AUTO:
        return next(cls for cls in DRIVERS.values() if cls.fits(model))()
    names = ", ".join((AUTO, *DRIVERS))
    cls = DRIVERS.get(name)
    if cls is None:
        raise DriverError(f"no driver {name!r}: choose one of {names}")
    problem = cls.mismatch(model)
    if problem is not None:
        raise DriverError(f"driver {name!r} cannot drive this robot: {problem} (drivers: {names})")
    return cls()
