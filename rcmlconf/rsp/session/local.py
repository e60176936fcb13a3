"""The local system's side of an RSP session, without I/O, in aioquic's shape.

It is the Robot Device Manager and both packet handlers of the paper's Fig. 2.

    local = LocalEndpoint(model)
    local.connect(now)                       # HELLO
    local.receive_datagram(data, now)        # WELCOME, UPLINK, ACK, BYE ...
    for data in local.datagrams_to_send(now): sock.send(data)
    local.get_timer(); local.handle_timer(now)
    local.next_event()                       # events.SessionOpened, StateReceived ...

The application calls the endpoint so:

- `write` sets an effector's values.
- `set_active` requests sensors, monitors and events, and activates modules.
- `issue` issues commands and memory commands.

Every period T, a DOWNLINK carries the active effectors' values, the module and request bits,
and the occurrences due (D-RSP-14, D-RSP-17, D-RSP-18).
"""

from __future__ import annotations

import os
from collections import deque
from collections.abc import Mapping

from rcmlconf.errors import ProtocolError
from rcmlconf.hotpath import make_namedtuple, members
from rcmlconf.rctp.datastream.order import Arrival, SequenceCounts
from rcmlconf.rsp.codec import (
    CLEAR_BUFFER,
    Bye,
    ByeReason,
    Encryption,
    Hello,
    Item,
    MapBody,
    PacketType,
    Period,
    Refused,
    Welcome,
    codec_for,
)
from rcmlconf.rsp.codec.bodies import MAX_PERIOD_MS, MIN_PERIOD_MS, Body, map_body
from rcmlconf.rsp.layout import MAC_SIZE, NONCE_SIZE
from rcmlconf.rsp.model import Device, DeviceKind, RobotModel
from rcmlconf.rsp.reliable import ReceivedIds, ReliableSender
from rcmlconf.rsp.security import Direction
from rcmlconf.rsp.session import events
from rcmlconf.rsp.session.devices import check_values, device
from rcmlconf.rsp.session.events import StateReceived
from rcmlconf.rsp.session.timing import Beat, Liveness, Silence
from rcmlconf.rsp.session.wire import SENT_TO_LOCAL, SessionWire, drop_unsent
from rcmlconf.values import Value
from rcmlconf.wording import indefinite

#: D-RSP-12: a HELLO without answer is sent again this often, this many times.
HELLO_INTERVAL = 0.25
HELLO_RETRIES = 5
#: D-RSP-13: PERIOD rides this many beats.
PERIOD_REPEATS = 3

_K = DeviceKind
#: Read every period, so held as globals (see `members`).
_DOWNLINK, _UPLINK = members(PacketType, "DOWNLINK", "UPLINK")
(_NEWER,) = members(Arrival, "NEWER")
#: What `set_active` means for each kind (D-RSP-14's DOWNLINK flags).
_REQUESTABLE = (_K.SENSOR, _K.MONITOR, _K.EVENT, _K.MEMORY_EVENT)
_ACTIVATABLE = (_K.EFFECTOR, _K.MODULE, *_REQUESTABLE)


class LocalEndpoint:
    """One session with one robot, from the local system (D-RSP-12)."""

    __slots__ = (
        "_active",
        "_beat",
        "_clear",
        "_credit",
        "_events",
        "_hello_at",
        "_hellos",
        "_live",
        "_nonce",
        "_out",
        "_period_repeats",
        "_psk",
        "_sender",
        "_standing",
        "_taken",
        "_values",
        "_wire",
        "codec",
        "encryption",
        "free_buffers",
        "model",
        "period",
        "state",
    )

    def __init__(
        self,
        model: RobotModel,
        *,
        period: float | None = None,
        encryption: Encryption = Encryption.NONE,
        psk: bytes | None = None,
        nonce: bytes | None = None,
    ) -> None:
        if encryption is not Encryption.NONE and psk is None:
            raise ValueError("an encrypted session needs the robot's pre-shared key")
        self.model = model
        self.codec = codec_for(model)
        self.period = model.period if period is None else period
        self.encryption = encryption
        self._psk = psk
        self._nonce = os.urandom(NONCE_SIZE) if nonce is None else nonce
        self._wire = SessionWire(self.codec, encryption, Direction.DOWNLINK)
        self.state = "idle"  # -> hello -> open -> closed
        self._out: list[bytes] = []
        self._events: deque[events.Event] = deque()
        self._hello_at = 0.0
        self._hellos = 0
        self._beat = Beat(self.period, 0.0)
        self._live = Liveness(self.period, 0.0)
        # The Robot Device Manager (paper §II.B): what every DOWNLINK carries.
        self._values: dict[int, dict[str, Value]] = {}
        self._active: set[int] = set()
        #: The items of them that every DOWNLINK carries, in model order (D-RSP-14, D-RSP-18).
        #: Only `write` and `set_active` change them. They set this to None, and the next
        #: DOWNLINK makes it again.
        self._standing: tuple[Item, ...] | None = None
        ids = 1 << (8 * model.id_length)
        self._sender = ReliableSender(ids, self.period)
        self._taken = ReceivedIds(ids)
        #: D-RSP-19: the robot's newest free count, and a Clear Buffer to send.
        self.free_buffers = model.command_buffers
        self._clear = False
        self._period_repeats = 0
        #: What `_may_start` has left of the free buffers in the beat being made.
        self._credit: int | None = None

    # -- the application's calls ---------------------------------------------------------------

    def connect(self, now: float) -> None:
        """Send HELLO (D-RSP-12)."""
        if self.state != "idle":
            raise RuntimeError(f"connect() in state {self.state}")
        self.state = "hello"
        self._send_hello(now)

    def write(self, name: str, values: Mapping[str, Value]) -> None:
        """An effector's value, in every DOWNLINK from now on (D-RSP-18); makes it active."""
        found = device(self.codec, name, (_K.EFFECTOR,), "be written")
        self._values[found.position] = check_values(
            self.codec, PacketType.DOWNLINK, found, values, None
        )
        self._active.add(found.position)
        self._standing = None

    def set_active(self, name: str, active: bool) -> None:
        """An effector's value sent or not; a sensor, monitor, event or memory event requested or
        not; a module active or not (D-RSP-14)."""
        found = device(self.codec, name, _ACTIVATABLE, "be activated or requested")
        if found.kind is _K.EFFECTOR and active and found.position not in self._values:
            raise ValueError(f"{name} has no value yet: write() it first")
        (self._active.add if active else self._active.discard)(found.position)
        self._standing = None

    def issue(self, name: str, values: Mapping[str, Value]) -> int:
        """A command or memory command; its ID (R-RSP-24). It goes when D-RSP-17 and D-RSP-19
        allow; `Backlog` when too many of the device wait."""
        found = device(self.codec, name, (_K.COMMAND, _K.MEMORY_COMMAND), "be issued")
        checked = check_values(self.codec, PacketType.DOWNLINK, found, values, 0)
        return self._sender.issue(found, checked)

    def clear_buffer(self) -> None:
        """Set Clear Buffer in the next DOWNLINK (R-RSP-33)."""
        self._clear = True

    def set_period(self, seconds: float, now: float) -> None:
        """T from now on; the robot hears it by PERIOD (D-RSP-13)."""
        period_ms = round(seconds * 1000)
        if not MIN_PERIOD_MS <= period_ms <= MAX_PERIOD_MS:
            raise ValueError(f"T is {MIN_PERIOD_MS} to {MAX_PERIOD_MS} ms, not {period_ms}")
        self.period = period_ms / 1000
        self._beat.period = self._live.period = self.period
        self._period_repeats = PERIOD_REPEATS
        if self.state == "open":
            self._send_period(now)

    def close(self, now: float) -> None:
        """BYE (reason 0) and the end of the session."""
        if self.state == "open":
            self._bye(ByeReason.CLOSED, now)
        self.state = "closed"

    def latest_free(self) -> int:
        """Memory commands that may start now (D-RSP-19)."""
        in_flight = sum(1 for o in self._sender.in_flight() if o.device.kind is _K.MEMORY_COMMAND)
        return max(self.free_buffers - in_flight, 0)

    @property
    def packets_sent(self) -> int:
        return self._wire.sent

    @property
    def received(self) -> SequenceCounts:
        """The robot's packets of this session: received, lost, late, duplicates (D-RSP-15)."""
        return self._wire.tracker.counts

    # -- I/O -----------------------------------------------------------------------------------

    def datagrams_to_send(self, now: float) -> list[bytes]:
        out, self._out = self._out, []
        return out

    def next_event(self) -> events.Event | None:
        return self._events.popleft() if self._events else None

    def next_beat(self) -> float | None:
        """When the next DOWNLINK is due (D-RSP-13); None without a session."""
        return self._beat.next if self.state == "open" else None

    def get_timer(self) -> float | None:
        if self.state == "hello":
            return self._hello_at
        if self.state == "open":
            return min(self._beat.next, self._live.deadline())
        return None

    def handle_timer(self, now: float) -> None:
        if self.state == "hello" and now >= self._hello_at:
            if self._hellos > HELLO_RETRIES:
                self.state = "closed"
                self._events.append(events.SessionRefused(None))
            else:
                self._send_hello(now)
        if self.state != "open":
            return
        silence = self._live.check(now)
        if silence is not None:  # most beats hear no silence, so they skip the enum lookups
            if silence is Silence.TIMEOUT:
                self._bye(ByeReason.TIMEOUT, now)
                return
            self._events.append(events.LinkLost())
        if self._beat.due(now):
            self._downlink(now)

    def receive_datagram(self, data: bytes, now: float) -> None:
        try:
            self._receive(data, now)
        except ProtocolError as exc:
            self._events.append(events.PacketDropped(exc.reason, exc.rule or "", exc.offset))

    # -- receiving -----------------------------------------------------------------------------

    def _receive(self, data: bytes, now: float) -> None:
        if self.state == "hello":
            self._answer(data, now)
            return
        if self.state != "open":
            return
        drop_unsent(data, SENT_TO_LOCAL, "the local system")
        packet, arrival = self._wire.read(data, self._psk)
        if self._live.heard(now):
            self._events.append(events.LinkRestored())
        header, body = packet
        kind = header.type
        if arrival is _NEWER:  # D-RSP-19: every robot packet gives its free buffers
            self.free_buffers = header.buffer
        if kind is _UPLINK:
            assert isinstance(body, MapBody)
            self._uplink(body, header.timestamp, arrival, now)
        elif kind is PacketType.ACK:
            assert isinstance(body, MapBody)
            for done, taken in self._sender.acknowledge(body.items, now):
                self._events.append(events.Acknowledged(done.device.name, done.id, taken))
        elif kind is PacketType.BYE:
            assert isinstance(body, Bye)
            self.state = "closed"
            self._events.append(events.SessionClosed(body.reason, by_peer=True))
        # Else it is a WELCOME again, answering a repeated HELLO. There is nothing to do. (A
        # REFUSED belongs to no session, and the wire has dropped it.)

    def _answer(self, data: bytes, now: float) -> None:
        """WELCOME or REFUSED to our HELLO (D-RSP-12)."""
        header = self.codec.pull_header(data)
        if header.type is PacketType.REFUSED:
            packet, _ = self._wire.read(data, self._psk)
            assert isinstance(packet.body, Refused)
            self.state = "closed"
            self._events.append(events.SessionRefused(packet.body.reason))
            return
        if header.type is not PacketType.WELCOME:
            raise ProtocolError(f"{indefinite(header.type.name)} before WELCOME", 4, "R-RSP-18")
        self._wire.session_id = header.session_id
        try:
            packet, _ = self._wire.read(data, self._psk)
            welcome = packet.body
            assert isinstance(welcome, Welcome)
            if welcome.client_nonce != self._nonce:
                raise ProtocolError("the WELCOME of another HELLO", 20, "R-RSP-18")
        except ProtocolError:
            self._wire.session_id = 0
            raise
        self._wire.secure(self._psk or b"", self._nonce, welcome.robot_nonce)
        self.free_buffers = header.buffer  # D-RSP-19: WELCOME gives the robot's free buffers
        self.period = welcome.period_ms / 1000
        self.state = "open"
        self._beat = Beat(self.period, now)
        self._live = Liveness(self.period, now)
        self._events.append(events.SessionOpened(header.session_id, self.period))

    def _uplink(self, body: MapBody, stamp: int, arrival: Arrival, now: float) -> None:
        newer = arrival is _NEWER
        acks = []
        devices = self.model.devices
        for position, ident, values in body.items:
            found = devices[position]
            assert values is not None
            if ident is None:
                if newer:  # R-RSP-19: a late packet's states are older than what we hold
                    self._events.append(make_namedtuple(StateReceived, (found.name, values, stamp)))
                continue
            if self._taken.take(position, ident):
                self._events.append(events.OccurrenceReceived(found.name, ident, values))
            if found.kind is _K.MEMORY_EVENT:  # R-RSP-26: new or repeated, at once
                acks.append(Item(position, ident))
        if acks:
            self._send(PacketType.ACK, MapBody(tuple(acks)), now)

    # -- sending -------------------------------------------------------------------------------

    def _send(self, kind: PacketType, body: Body, now: float, buffer: int = 0) -> None:
        self._out.append(self._wire.build(kind, body, now, buffer, self._psk))

    def _send_hello(self, now: float) -> None:
        self._hellos += 1
        self._hello_at = now + HELLO_INTERVAL
        # In an encrypted session SessionWire.build puts the MAC in the place kept for it.
        mac = bytes(MAC_SIZE) if self.encryption is not Encryption.NONE else b""
        self._send(PacketType.HELLO, Hello(self._nonce, round(self.period * 1000), mac), now)

    def _send_period(self, now: float) -> None:
        self._period_repeats -= 1
        self._send(PacketType.PERIOD, Period(round(self.period * 1000)), now)

    def _bye(self, reason: ByeReason, now: float) -> None:
        self._send(PacketType.BYE, Bye(reason), now)
        self.state = "closed"
        self._events.append(events.SessionClosed(reason, by_peer=False))

    def _downlink(self, now: float) -> None:
        if self._period_repeats > 0:
            self._send_period(now)
        standing = self._standing
        if standing is None:  # effector values, module and request bits
            values = self._values
            standing = tuple([Item(p, None, values.get(p)) for p in sorted(self._active)])
            self._standing = standing
        self._credit = None  # counted at the first memory command due; most beats have none
        due = self._sender.due(now, self._may_start)
        carried = standing
        if due:
            items = {item.device: item for item in standing}
            for occurrence in due:
                position = occurrence.device.position
                items[position] = Item(position, occurrence.id, occurrence.values)
            carried = tuple([items[p] for p in sorted(items)])
        buffer = CLEAR_BUFFER if self._clear else 0
        if not carried and not buffer and not self._beat.quiet():
            return
        self._beat.sent()
        if buffer:
            self._clear = False
            self.free_buffers = self.model.command_buffers
        self._send(_DOWNLINK, map_body(carried), now, buffer)
        self._sender.sent(due, now)

    def _may_start(self, found: Device) -> bool:
        """D-RSP-19: a memory command starts only into a free buffer of the robot's."""
        if found.kind is not _K.MEMORY_COMMAND:
            return True
        credit = (self.latest_free() if self._credit is None else self._credit) - 1
        self._credit = credit
        return credit >= 0
