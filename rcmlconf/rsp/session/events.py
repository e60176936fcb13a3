"""What an RSP endpoint tells its application (`next_event()` of `LocalEndpoint` and
`RobotEndpoint`). Devices are named; values are field name -> value, as the codec gives them."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import NamedTuple

from rcmlconf.rsp.codec import ByeReason, RefusedReason
from rcmlconf.values import Value

Address = tuple[str, int]


@dataclass(frozen=True, slots=True)
class SessionOpened:
    """WELCOME given (robot) or received (local) (D-RSP-12)."""

    session_id: int
    #: The period in force, seconds (D-RSP-13).
    period: float
    peer: Address | None = None


@dataclass(frozen=True, slots=True)
class SessionRefused:
    """The robot refused the HELLO, or never answered it (reason None) (D-RSP-12)."""

    reason: RefusedReason | None


@dataclass(frozen=True, slots=True)
class SessionClosed:
    """BYE sent or received, or the session timed out (R-RSP-22)."""

    reason: ByeReason
    #: Whether the peer said so (a BYE received) rather than this side.
    by_peer: bool


@dataclass(frozen=True, slots=True)
class LinkLost:
    """Nothing from the peer for 25 periods (D-RSP-13)."""


@dataclass(frozen=True, slots=True)
class LinkRestored:
    """A packet from the peer after the link was lost."""


class StateReceived(NamedTuple):
    """A newer packet's value of a device (D-RSP-15, D-RSP-18): a sensor's or monitor's at the
    local system, an effector's at the robot. A NamedTuple, as `Header` is: one is made for every
    value of every packet, and a frozen dataclass costs three times as much to make."""

    device: str
    values: Mapping[str, Value]
    #: The packet's timestamp, milliseconds of the sender's clock (D-RSP-10).
    stamp: int


@dataclass(frozen=True, slots=True)
class OccurrenceReceived:
    """A new occurrence, taken once (R-RSP-25): an event or memory event at the local system, a
    command or memory command at the robot (a memory command when the robot's buffer took it)."""

    device: str
    id: int
    values: Mapping[str, Value]


@dataclass(frozen=True, slots=True)
class Acknowledged:
    """The peer acknowledged an occurrence this side sent (D-RSP-17)."""

    device: str
    id: int
    #: Seconds from its first send to its ACK.
    after: float


@dataclass(frozen=True, slots=True)
class PacketDropped:
    """A datagram dropped unread and unanswered (R-RSP-18)."""

    reason: str
    rule: str
    offset: int | None = None


Event = (
    SessionOpened
    | SessionRefused
    | SessionClosed
    | LinkLost
    | LinkRestored
    | StateReceived
    | OccurrenceReceived
    | Acknowledged
    | PacketDropped
)
