"""Occurrences and selective retransmission (D-RSP-16, D-RSP-17), without I/O.

A *sender* of commands, memory commands or memory events keeps each occurrence until its ACK,
one per device at a time, so that a device's occurrences are taken in order (R-RSP-29); a command
rides every packet until then, a memory command or memory event waits a retransmission timeout
between sends (R-RSP-27, R-RSP-28). Events are not acknowledged: they ride three packets
(R-RSP-30). A *receiver* takes each ID once (R-RSP-25) and acknowledges every reliable one it sees.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import dataclass, field

from rcmlconf.rsp.codec import Item
from rcmlconf.rsp.model import Device, DeviceKind
from rcmlconf.values import Value

#: D-RSP-17: the retransmission timeout's bounds.
MAX_RTO = 2.0
#: Before the first round trip is measured, this many periods.
INITIAL_RTO_PERIODS = 10
#: D-RSP-17: an event rides this many packets.
EVENT_REPEATS = 3
#: Occurrences of one device waiting behind the one in flight, at most: an application that
#: issues faster than the link delivers is told so (`Backlog`) rather than buffered without end.
MAX_QUEUED = 256


class Backlog(Exception):
    """A device already has MAX_QUEUED occurrences waiting to be sent."""


class RetransmissionTimer:
    """RFC 6298's estimator: RTO = SRTT + 4 * RTTVAR within [2T, 2 s] (D-RSP-17)."""

    __slots__ = ("_floor", "rto", "rttvar", "srtt")

    def __init__(self, period: float) -> None:
        self._floor = 2 * period
        self.srtt: float | None = None
        self.rttvar = 0.0
        self.rto = self._bounded(INITIAL_RTO_PERIODS * period)

    def _bounded(self, seconds: float) -> float:
        return min(max(seconds, self._floor), MAX_RTO)

    def sample(self, rtt: float) -> None:
        """One round trip of an occurrence sent once (Karn's rule: never one sent twice)."""
        if self.srtt is None:
            self.srtt, self.rttvar = rtt, rtt / 2
        else:
            self.rttvar = 0.75 * self.rttvar + 0.25 * abs(self.srtt - rtt)
            self.srtt = 0.875 * self.srtt + 0.125 * rtt
        self.rto = self._bounded(self.srtt + 4 * self.rttvar)

    def back_off(self) -> None:
        self.rto = self._bounded(2 * self.rto)


@dataclass(slots=True)
class Occurrence:
    device: Device
    id: int
    values: Mapping[str, Value]
    #: When it was first and last sent; None before it was.
    first_sent: float | None = None
    last_sent: float | None = None
    sends: int = 0


@dataclass(slots=True)
class _Queue:
    next_id: int = 0
    waiting: deque[Occurrence] = field(default_factory=deque)


class ReliableSender:
    """One side's commands and memory commands, or memory events, until acknowledged."""

    __slots__ = ("_id_space", "_queues", "timer")

    def __init__(self, id_space: int, period: float) -> None:
        self._id_space = id_space
        self.timer = RetransmissionTimer(period)
        self._queues: dict[int, _Queue] = {}

    def issue(self, device: Device, values: Mapping[str, Value]) -> int:
        """A new occurrence of `device` (R-RSP-24): its ID."""
        queue = self._queues.setdefault(device.position, _Queue())
        if len(queue.waiting) > MAX_QUEUED:
            raise Backlog(f"{device.name} has {MAX_QUEUED} occurrences waiting already")
        occurrence = Occurrence(device, queue.next_id, values)
        queue.next_id = (queue.next_id + 1) % self._id_space
        queue.waiting.append(occurrence)
        return occurrence.id

    def due(self, now: float, may_start: Callable[[Device], bool]) -> list[Occurrence]:
        """The occurrences the next packet carries: each device's oldest one, when it is a
        command (every packet, R-RSP-27), or when it was never sent or its timeout passed
        (R-RSP-28). `may_start` can hold back one never sent (D-RSP-19's free buffers)."""
        carried = []
        for queue in self._queues.values():
            if not queue.waiting:
                continue
            head = queue.waiting[0]
            if head.last_sent is None:
                if not may_start(head.device):
                    continue
            elif head.device.kind is not DeviceKind.COMMAND and now < self.resend_at(head):
                continue
            carried.append(head)
        return carried

    def sent(self, occurrences: list[Occurrence], now: float) -> None:
        """They left in a packet at `now`."""
        for occurrence in occurrences:
            timed_out = occurrence.device.kind is not DeviceKind.COMMAND
            if occurrence.last_sent is not None and timed_out:
                self.timer.back_off()  # a retransmission after a timeout (RFC 6298 §5.5)
            if occurrence.first_sent is None:
                occurrence.first_sent = now
            occurrence.last_sent = now
            occurrence.sends += 1

    def resend_at(self, occurrence: Occurrence) -> float:
        assert occurrence.last_sent is not None
        return occurrence.last_sent + self.timer.rto

    def acknowledged(self, device: int, occurrence_id: int, now: float) -> Occurrence | None:
        """An ACK: the occurrence it ends, if it is the one in flight (else a stale ACK)."""
        queue = self._queues.get(device)
        if queue is None or not queue.waiting:
            return None
        head = queue.waiting[0]
        if head.id != occurrence_id or head.first_sent is None:
            return None
        queue.waiting.popleft()
        if head.sends == 1:  # Karn's rule: only an occurrence sent once times the round trip
            self.timer.sample(now - head.first_sent)
        return head

    def acknowledge(self, items: Iterable[Item], now: float) -> Iterator[tuple[Occurrence, float]]:
        """An ACK's items (R-RSP-26): each occurrence one ends, with the time since it was first
        sent (a stale ACK ends none)."""
        for item in items:
            assert item.id is not None  # an ACK's items name occurrences (D-RSP-14)
            done = self.acknowledged(item.device, item.id, now)
            if done is not None and done.first_sent is not None:
                yield done, now - done.first_sent

    def in_flight(self) -> list[Occurrence]:
        """Sent and not yet acknowledged."""
        return [q.waiting[0] for q in self._queues.values() if q.waiting and q.waiting[0].sends]

    def get_timer(self) -> float | None:
        """When a memory command or memory event is next due again (commands ride the beat)."""
        times = [
            self.resend_at(occurrence)
            for occurrence in self.in_flight()
            if occurrence.device.kind is not DeviceKind.COMMAND
        ]
        return min(times, default=None)

    def waiting(self) -> int:
        return sum(len(q.waiting) for q in self._queues.values())


class ReceivedIds:
    """Per device, the last ID taken: what is new (D-RSP-16)."""

    __slots__ = ("_half", "_last", "_space")

    def __init__(self, id_space: int) -> None:
        self._half = id_space // 2
        self._space = id_space
        self._last: dict[int, int] = {}

    def is_new(self, device: int, occurrence_id: int) -> bool:
        last = self._last.get(device)
        return last is None or 1 <= (occurrence_id - last) % self._space <= self._half

    def take(self, device: int, occurrence_id: int) -> bool:
        """Whether the occurrence is new; a new one is taken and is no longer new."""
        if not self.is_new(device, occurrence_id):
            return False
        self._last[device] = occurrence_id
        return True


@dataclass(slots=True)
class _Repeated:
    occurrence: Occurrence
    left: int


class EventRepeater:
    """Events ride the next EVENT_REPEATS packets (D-RSP-17); a newer one of the same device
    waits for the older one's last ride, so none is skipped."""

    __slots__ = ("_id_space", "_next_id", "_queues")

    def __init__(self, id_space: int) -> None:
        self._id_space = id_space
        self._next_id: dict[int, int] = {}
        self._queues: dict[int, deque[_Repeated]] = {}

    def occur(self, device: Device, values: Mapping[str, Value]) -> int:
        occurrence_id = self._next_id.get(device.position, 0)
        self._next_id[device.position] = (occurrence_id + 1) % self._id_space
        queue = self._queues.setdefault(device.position, deque())
        if len(queue) > MAX_QUEUED:
            raise Backlog(f"{device.name} has {MAX_QUEUED} events waiting already")
        queue.append(_Repeated(Occurrence(device, occurrence_id, values), EVENT_REPEATS))
        return occurrence_id

    def ride(self) -> list[Occurrence]:
        """The events of the next packet: each device's oldest, one ride used up."""
        riding = []
        for queue in self._queues.values():
            if queue:
                head = queue[0]
                riding.append(head.occurrence)
                head.left -= 1
                if head.left == 0:
                    queue.popleft()
        return riding
