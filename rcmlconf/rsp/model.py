"""A robot model as data (specs/rsp.md §1): the devices of Table I in model order, and their fields.

Unlike an RCML tree, a model is an ordered list (D-RSP-2): `RobotModel.devices[i]` is the device
of Device Map bit i (its `position`). Fields are RCML's data types (D-RSP-4), so `rcmlconf.values`
encodes them.
"""

from __future__ import annotations

import enum
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import NamedTuple

from rcmlconf.values import Value, ValueType
from rcmlconf.values.declared import zero_value

#: D-RSP-6: the paper's transmission period T; D-RSP-13: the range it may take, in seconds.
DEFAULT_PERIOD = 0.02
MIN_PERIOD = 0.005
MAX_PERIOD = 10.0
#: D-RSP-5, D-RSP-6: the values the model's attributes may take.
ID_LENGTHS = (1, 2)
DEFAULT_ID_LENGTH = 1
MAX_COMMAND_BUFFERS = 127
DEFAULT_COMMAND_BUFFERS = 16
MAX_MODEL_ID = 65535
#: D-RSP-7.
MAX_DEVICES = 1024


class DeviceKind(enum.Enum):
    """Table I's eight element kinds; the value is the element's name."""

    MODULE = "module"
    EFFECTOR = "effector"
    SENSOR = "sensor"
    MONITOR = "monitor"
    COMMAND = "command"
    EVENT = "event"
    MEMORY_COMMAND = "memoryCommand"
    MEMORY_EVENT = "memoryEvent"

    @property
    def occurrence(self) -> bool:
        """Each one sent is new and carries an ID (D-RSP-5)."""
        return self in _OCCURRENCES

    @property
    def reliable(self) -> bool:
        """Acknowledged and sent again until acknowledged (D-RSP-17)."""
        return self in _RELIABLE

    @property
    def has_fields(self) -> bool:
        """Declares `field`s of its own (a monitor borrows its effector's, a module has none)."""
        return self not in (DeviceKind.MODULE, DeviceKind.MONITOR)


_OCCURRENCES = frozenset(
    {DeviceKind.COMMAND, DeviceKind.EVENT, DeviceKind.MEMORY_COMMAND, DeviceKind.MEMORY_EVENT}
)
_RELIABLE = frozenset({DeviceKind.COMMAND, DeviceKind.MEMORY_COMMAND, DeviceKind.MEMORY_EVENT})


class OnLoss(enum.Enum):
    """What an effector does while the link is lost (D-RSP-20)."""

    HOLD = "hold"
    ZERO = "zero"


class Meta(NamedTuple):
    name: str
    content: str


class Field(NamedTuple):
    name: str
    type: ValueType
    minimum: int | float | None = None
    maximum: int | float | None = None
    #: For people (`mm/s`).
    unit: str | None = None
    meta: tuple[Meta, ...] = ()

    def zero(self) -> Value:
        """D-RSP-20's safe value: a number nearest 0 within the field's range (for
        `onLoss="zero"`, and before any value arrived), false, or empty text or bytes."""
        return zero_value(self.type, self.minimum, self.maximum)


class Device(NamedTuple):
    #: Its place in model order, which is its bit in the Device Map (D-RSP-14).
    position: int
    name: str
    kind: DeviceKind
    #: The payload's fields in order; a monitor's are its effector's, a module has none.
    fields: tuple[Field, ...] = ()
    #: The module holding it, if any.
    module: str | None = None
    #: A monitor's effector.
    of: str | None = None
    on_loss: OnLoss = OnLoss.HOLD
    meta: tuple[Meta, ...] = ()


@dataclass(frozen=True)
class RobotModel:
    """A valid robot model."""

    name: str
    #: D-RSP-6: in every packet header.
    model_id: int
    #: Model order (D-RSP-2).
    devices: tuple[Device, ...]
    id_length: int = DEFAULT_ID_LENGTH
    command_buffers: int = DEFAULT_COMMAND_BUFFERS
    #: Seconds (D-RSP-13).
    period: float = DEFAULT_PERIOD
    title: str | None = None
    author: str | None = None
    meta: tuple[Meta, ...] = ()
    by_name: Mapping[str, Device] = field(default_factory=dict, compare=False, repr=False)

    def device(self, name: str) -> Device | None:
        return self.by_name.get(name)

    def members(self, module: str) -> tuple[Device, ...]:
        """The devices a module holds (D-RSP-3)."""
        return tuple(d for d in self.devices if d.module == module)

    @property
    def map_size(self) -> int:
        """Bytes of the Device Map (D-RSP-14)."""
        return (len(self.devices) + 7) // 8
