"""Robot drivers: what the reference server controls (issue 5).

A driver owns the values of a robot's data nodes. The server asks it for values, hands it the
values clients write (already checked for type, range, permission and privilege), and lets it move
to the present so that streams and events carry real changes. Simulated robots ship as examples;
a real robot is one more class with these four methods.

Drivers are pure: time comes in as `now` (seconds, any epoch), randomness from the seed given to
`start`, so a run is repeatable and a test can step a driver by hand.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Protocol

from rcmlconf.rcml.model import RcmlDocument
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
