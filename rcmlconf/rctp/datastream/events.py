"""What a data-stream endpoint tells its application (`endpoint.Endpoint.next_event`)."""

from __future__ import annotations

from dataclasses import dataclass

from rcmlconf.rctp.datastream.clock import ClockEstimate
from rcmlconf.rctp.datastream.flow import Direction, FlowMessage
from rcmlconf.values import Value


@dataclass(frozen=True, slots=True)
class ValuesReceived:
    """A newer packet's DATA payload, decoded and within range: the stream's state now
    (D-RCTP-20, D-RCTP-21)."""

    stream: int
    values: dict[str, Value]
    #: When the peer sent the packet, by its clock (64-bit NTP).
    sent: int


@dataclass(frozen=True, slots=True)
class PacketDropped:
    """A datagram dropped unread and unanswered (R-RCTP-42): wrong source, tag or framing."""

    reason: str
    rule: str
    #: Where in the datagram, when the fault has a place.
    offset: int | None = None


@dataclass(frozen=True, slots=True)
class PayloadIgnored:
    """One payload of a readable packet left unapplied: stale, unknown, broken or out of range."""

    stream: int
    reason: str
    rule: str
    offset: int | None = None


@dataclass(frozen=True, slots=True)
class FlowRequested:
    """The peer asked; this side answered (`answer`), and applied what the answer says."""

    stream: int
    request: FlowMessage
    answer: FlowMessage


@dataclass(frozen=True, slots=True)
class FlowAnswered:
    """This side's request got its ACK or NACK; what an ACK reports is now recorded."""

    stream: int
    request: FlowMessage
    answer: FlowMessage


@dataclass(frozen=True, slots=True)
class FlowUnanswered:
    """A request sent five times, 250 ms apart, got no answer (D-RCTP-22)."""

    stream: int
    request: FlowMessage


@dataclass(frozen=True, slots=True)
class ClockUpdated:
    """A heartbeat's answer changed the estimate of the peer's clock (D-RCTP-24)."""

    estimate: ClockEstimate


@dataclass(frozen=True, slots=True)
class StreamTimedOut:
    """No DATA of a playing stream for its receive timeout (D-RCTP-23): the stream is lost.

    The endpoint stops watching it; a server answers with STOP (`Reason: timeout`, R-RCTP-45).
    """

    stream: int
    direction: Direction


StreamEvent = (
    ValuesReceived
    | PacketDropped
    | PayloadIgnored
    | FlowRequested
    | FlowAnswered
    | FlowUnanswered
    | ClockUpdated
    | StreamTimedOut
)
