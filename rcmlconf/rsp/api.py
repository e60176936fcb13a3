"""What the Robot API (paper §II.B, Fig. 4) needs of the local middleware, by device name.

The simulacrum (`rcmlconf.reference.local`) provides it; `rcmlconf rsp generate` writes typed
classes over it, one per device (the paper's module creator), so that an application calls
`cubo.left_wheel.write(speed=120)` rather than naming devices and fields in strings. Values are
mappings of field name to value (`rcmlconf.values.Value`), as the codec carries them.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Protocol

from rcmlconf.values import Value

Values = Mapping[str, Value]


class DeviceAccess(Protocol):
    """The Robot Device Manager and the Robot Environment Data Buffer, as one object. Every
    method may be called from any thread; names are checked (KeyError for an unknown device,
    TypeError for a call its kind does not have, EncodeError for values it cannot send)."""

    def write(self, device: str, values: Values) -> None:
        """An effector's new value, sent in every DOWNLINK from now on (D-RSP-18); it also makes
        the effector active."""

    def set_active(self, device: str, active: bool) -> None:
        """An effector: whether its value goes in DOWNLINKs. A sensor, monitor, event or memory
        event: whether its bit requests it (D-RSP-14). A module: whether it is active."""

    def latest(self, device: str) -> Values | None:
        """The newest value of a sensor or monitor (None before any arrived), or the value last
        written to an effector."""

    def read(self, device: str, timeout: float | None = None) -> Values:
        """Wait for a value of a sensor or monitor newer than the one the last `read` of it gave,
        or the next occurrence of an event or memory event; TimeoutError after `timeout` s."""

    def issue(self, device: str, values: Values) -> int:
        """A command or memory command: queue an occurrence; returns its ID (D-RSP-5)."""

    def listen(self, device: str, listener: Callable[[Values], None]) -> Callable[[], None]:
        """Call `listener` with each new value or occurrence of a sensor, monitor, event or memory
        event, from the middleware's thread; returns the function that stops it."""
