"""The robot's side of RSP, without I/O.

It is the packet handler and the processors of the paper's §II.B: motion, sensor and security.
The audio processor is `rsp.audio`; the application feeds it.

    robot = RobotEndpoint(model)
    robot.receive_datagram(data, addr, now)     # HELLO, DOWNLINK, ACK, PERIOD, BYE
    for data, addr in robot.datagrams_to_send(now): sock.sendto(data, addr)
    robot.get_timer(); robot.handle_timer(now)
    robot.next_event()                          # events.SessionOpened, OccurrenceReceived ...

The application is a robot driver. It calls the endpoint so:

- `effectors(now)` says what the effectors are to do: the motion filter's output (D-RSP-20).
- `take_memory_command` gives the memory commands one at a time (D-RSP-19).
- `set_state` reports sensors and monitors; `occur` reports events and memory events.

One session runs at a time, because a session drives the robot. A second local system gets
REFUSED 3.
"""

from __future__ import annotations

import os
from collections import deque
from collections.abc import Callable, Mapping
from dataclasses import dataclass

from rcmlconf.errors import ProtocolError
from rcmlconf.hotpath import make_namedtuple, members
from rcmlconf.rctp.datastream.order import Arrival
from rcmlconf.rsp.codec import (
    CLEAR_BUFFER,
    Bye,
    ByeReason,
    Encryption,
    Header,
    Hello,
    Item,
    MapBody,
    PacketType,
    Period,
    Refused,
    RefusedReason,
    Welcome,
    codec_for,
    pull_header,
    push_header,
)
from rcmlconf.rsp.codec.bodies import Body, map_body
from rcmlconf.rsp.layout import MAC_SIZE, NONCE_SIZE, Bit, MapPacket, bit
from rcmlconf.rsp.model import Device, DeviceKind, RobotModel
from rcmlconf.rsp.motion import MotionFilter
from rcmlconf.rsp.reliable import EventRepeater, Occurrence, ReceivedIds, ReliableSender
from rcmlconf.rsp.security import Direction
from rcmlconf.rsp.session import events
from rcmlconf.rsp.session.devices import check_values, device, same_values
from rcmlconf.rsp.session.events import StateReceived
from rcmlconf.rsp.session.timing import Beat, Liveness, Silence
from rcmlconf.rsp.session.wire import SENT_TO_ROBOT, SessionWire, drop_unsent
from rcmlconf.values import Value
from rcmlconf.wording import indefinite

_K = DeviceKind
Address = events.Address
#: The type byte of a HELLO, which may come while a session is open (D-RSP-12).
_HELLO = bytes([PacketType.HELLO])
#: 48-bit session IDs (D-RSP-10).
_SESSION_BITS = 48
#: Read every period, so held as globals (see `members`).
_DOWNLINK, _UPLINK = members(PacketType, "DOWNLINK", "UPLINK")
(_NEWER,) = members(Arrival, "NEWER")


@dataclass(slots=True)
class RobotSession:
    peer: Address
    wire: SessionWire
    client_nonce: bytes
    #: The WELCOME given, sent again to a repeated HELLO (D-RSP-12).
    welcome: bytes
    beat: Beat
    live: Liveness
    motion: MotionFilter
    #: The last command and memory command ID taken per device (D-RSP-16).
    commands: ReceivedIds
    #: The newest DOWNLINK's request and module bits (D-RSP-14).
    requested: frozenset[int] = frozenset()
    active_modules: frozenset[int] = frozenset()


class RobotEndpoint:
    """A robot's RSP side for one model.

    A robot that breaks RSP on purpose, to test a conformance harness, is a subclass. It
    overrides the protected methods where its bugs sit. `_welcome_again`, `_time_out` and
    `_stop_on_loss` exist as seams for such subclasses, on rare paths. The beat's methods have
    no seams, to keep them fast.
    """

    __slots__ = (
        "_buffer",
        "_events",
        "_events_out",
        "_idle",
        "_ids",
        "_memory_events",
        "_min_period_ms",
        "_module_of",
        "_modules",
        "_out",
        "_psk",
        "_random",
        "_reported",
        "_states",
        "codec",
        "encryptions",
        "model",
        "session",
    )

    def __init__(
        self,
        model: RobotModel,
        *,
        encryptions: frozenset[Encryption] = frozenset({Encryption.NONE}),
        psk: bytes | None = None,
        min_period: float | None = None,
        random: Callable[[int], bytes] = os.urandom,
    ) -> None:
        if any(e is not Encryption.NONE for e in encryptions) and psk is None:
            raise ValueError("encrypted sessions need the robot's pre-shared key")
        self.model = model
        self.codec = codec_for(model)
        self.encryptions = encryptions
        self._psk = psk
        self._min_period_ms = round((model.period if min_period is None else min_period) * 1000)
        self._random = random
        self._ids = 1 << (8 * model.id_length)
        self.session: RobotSession | None = None
        self._out: list[tuple[bytes, Address]] = []
        self._events: deque[events.Event] = deque()
        #: Sensor and monitor values, newest first set by the application.
        self._states: dict[int, dict[str, Value]] = {}
        self._events_out = EventRepeater(self._ids)
        self._memory_events = ReliableSender(self._ids, model.period)
        #: D-RSP-19: memory commands taken and not yet started.
        self._buffer: deque[Occurrence] = deque()
        #: What the effectors do without a session: their zero values (D-RSP-20).
        self._idle = MotionFilter(model, model.period)
        self._reported = {
            d.position for d in model.devices if bit(d.kind, MapPacket.UPLINK) is Bit.STATE
        }
        #: D-RSP-14: the modules, and the module of each device by position. None means in no
        #: module; -1 means a module the model lacks, which is never active. The model is
        #: immutable, so this is worked out once here, not by name for every item.
        self._modules = frozenset(d.position for d in model.devices if d.kind is _K.MODULE)
        self._module_of = [_module_position(model, d) for d in model.devices]

    # -- the robot application's calls ---------------------------------------------------------

    @property
    def free_buffers(self) -> int:
        return self.model.command_buffers - len(self._buffer)

    def set_state(self, name: str, values: Mapping[str, Value]) -> None:
        """A sensor's or monitor's newest value, for the UPLINKs that request it (D-RSP-18)."""
        found = device(self.codec, name, (_K.SENSOR, _K.MONITOR), "report a state")
        held = self._states.get(found.position)
        if held is not None and same_values(held, values):
            # A body reports every tick, mostly the same values as before. The values held
            # were checked and copied already, so checking these again would change nothing
            # (D-RSP-18).
            return
        self._states[found.position] = check_values(
            self.codec, PacketType.UPLINK, found, values, None
        )

    def reporting(self) -> list[str]:
        """The sensors and monitors that the next UPLINK carries.

        They are those the newest DOWNLINK requested, in an active module (D-RSP-14). Only these
        are worth measuring and passing to `set_state`.
        """
        session = self.session
        if session is None:
            return []
        devices = self.model.devices
        return [
            devices[p].name
            for p in sorted(self._reported & session.requested)
            if self._in_active(session, p)
        ]

    def occur(self, name: str, values: Mapping[str, Value]) -> int | None:
        """Report an event or memory event, and return its ID.

        Returns None when the local system has not requested the device. Nothing of an
        unrequested device is reported (D-RSP-14).
        """
        found = device(self.codec, name, (_K.EVENT, _K.MEMORY_EVENT), "occur")
        checked = check_values(self.codec, PacketType.UPLINK, found, values, 0)
        if not self._reports(found.position):
            return None
        if found.kind is _K.EVENT:
            return self._events_out.occur(found, checked)
        return self._memory_events.issue(found, checked)

    def effectors(self, now: float) -> dict[str, dict[str, Value]]:
        """What every effector is to do now (D-RSP-20); zero values before any session."""
        motion = self._idle if self.session is None else self.session.motion
        return motion.output(now)

    def take_memory_command(self) -> Occurrence | None:
        """The next memory command to execute, in the order taken (D-RSP-19)."""
        return self._buffer.popleft() if self._buffer else None

    def close(self, now: float) -> None:
        if self.session is not None:
            self._bye(ByeReason.SHUTDOWN, now)

    # -- I/O -----------------------------------------------------------------------------------

    def datagrams_to_send(self, now: float) -> list[tuple[bytes, Address]]:
        out, self._out = self._out, []
        return out

    def next_event(self) -> events.Event | None:
        return self._events.popleft() if self._events else None

    @property
    def period(self) -> float:
        """T now, in seconds: the session's if one is open, else the model's.

        A PERIOD packet changes the session's T (D-RSP-13).
        """
        return self.session.beat.period if self.session is not None else self.model.period

    def next_beat(self) -> float | None:
        """When the next UPLINK is due (D-RSP-13); None without a session."""
        return self.session.beat.next if self.session is not None else None

    def get_timer(self) -> float | None:
        session = self.session
        if session is None:
            return None
        return min(session.beat.next, session.live.deadline())

    def handle_timer(self, now: float) -> None:
        session = self.session
        if session is None:
            return
        silence = session.live.check(now)
        if silence is not None:  # most beats hear no silence, so they skip the enum lookups
            if silence is Silence.TIMEOUT:
                self._time_out(now)
                return
            self._stop_on_loss(session)
            self._events.append(events.LinkLost())
        if session.beat.due(now):
            self._uplink(session, now)

    def receive_datagram(self, data: bytes, peer: Address, now: float) -> None:
        try:
            self._receive(data, peer, now)
        except ProtocolError as exc:
            self._events.append(events.PacketDropped(exc.reason, exc.rule or "", exc.offset))

    # -- receiving -----------------------------------------------------------------------------

    def _receive(self, data: bytes, peer: Address, now: float) -> None:
        session = self.session
        if session is None or peer != session.peer or data[4:5] == _HELLO:
            header = pull_header(data)
            if header.type is not PacketType.HELLO:
                raise ProtocolError(
                    f"{indefinite(header.type.name)} from outside a session", 4, "R-RSP-18"
                )
            self._hello(header, data, peer, now)
            return
        drop_unsent(data, SENT_TO_ROBOT, "a robot")
        packet, arrival = session.wire.read(data, self._psk)
        header, body = packet
        if session.live.heard(now):
            self._events.append(events.LinkRestored())
        kind = header.type
        if kind is _DOWNLINK:
            assert isinstance(body, MapBody)
            self._downlink(session, header, body, arrival, now)
        elif kind is PacketType.ACK:
            assert isinstance(body, MapBody)
            for done, taken in self._memory_events.acknowledge(body.items, now):
                self._events.append(events.Acknowledged(done.device.name, done.id, taken))
        elif kind is PacketType.PERIOD:
            assert isinstance(body, Period)
            if arrival is _NEWER:
                self._set_period(session, body.period_ms, now)
        elif kind is PacketType.BYE:
            assert isinstance(body, Bye)
            self._end(events.SessionClosed(body.reason, by_peer=True))

    def _hello(self, header: Header, data: bytes, peer: Address, now: float) -> None:
        """R-RSP-20, R-RSP-21, R-RSP-38: WELCOME, the WELCOME given again, or REFUSED."""
        if header.model_id != self.model.model_id:
            self._refuse(header, RefusedReason.UNKNOWN_MODEL, peer, now)
            return
        if header.encryption not in self.encryptions:
            self._refuse(header, RefusedReason.ENCRYPTION_NOT_OFFERED, peer, now)
            return
        wire = SessionWire(self.codec, header.encryption, Direction.UPLINK)
        try:
            packet, _ = wire.read(data, self._psk)
        except ProtocolError as exc:
            if exc.rule == "R-RSP-38":
                self._refuse(header, RefusedReason.NOT_AUTHENTICATED, peer, now)
                return
            raise
        hello = packet.body
        assert isinstance(hello, Hello)
        session = self.session
        if session is not None and session.peer == peer:
            if hello.client_nonce == session.client_nonce:
                self._welcome_again(session)
                return
            # The same local system with a new nonce lost its session: the new one replaces it.
            self._end(events.SessionClosed(ByeReason.CLOSED, by_peer=True))
        elif session is not None:
            self._refuse(header, RefusedReason.BUSY, peer, now)
            return
        self._open(wire, hello, peer, now)

    def _open(self, wire: SessionWire, hello: Hello, peer: Address, now: float) -> None:
        wire.session_id = self._new_session_id()
        period_ms = max(hello.period_ms, self._min_period_ms)
        robot_nonce = self._random(NONCE_SIZE)
        signed = wire.encryption is not Encryption.NONE
        welcome = Welcome(
            hello.client_nonce, robot_nonce, period_ms, bytes(MAC_SIZE) if signed else b""
        )
        data = wire.build(PacketType.WELCOME, welcome, now, self.free_buffers, self._psk)
        wire.secure(self._psk or b"", hello.client_nonce, robot_nonce)
        period = period_ms / 1000
        self.session = RobotSession(
            peer,
            wire,
            hello.client_nonce,
            data,
            Beat(period, now + period),
            Liveness(period, now),
            MotionFilter(self.model, period),
            ReceivedIds(self._ids),
        )
        self._buffer.clear()
        self._memory_events = ReliableSender(self._ids, period)
        self._events_out = EventRepeater(self._ids)
        self._out.append((data, peer))
        self._events.append(events.SessionOpened(wire.session_id, period, peer))

    def _welcome_again(self, session: RobotSession) -> None:
        """A repeated HELLO (the session's nonce) gets the WELCOME given (D-RSP-12, R-RSP-20)."""
        self._out.append((session.welcome, session.peer))

    def _new_session_id(self) -> int:
        """R-RSP-20: random, never 0 (and only one session is open at a time)."""
        while True:
            session_id = int.from_bytes(self._random(_SESSION_BITS // 8))
            if session_id:
                return session_id

    def _refuse(self, header: Header, reason: RefusedReason, peer: Address, now: float) -> None:
        """Send REFUSED (D-RSP-12).

        REFUSED belongs to no session. It echoes the HELLO's model ID and encryption byte, so
        that a local system of another model can read it too.
        """
        refused = Header(
            1,
            header.model_id,
            header.encryption,
            PacketType.REFUSED,
            0,
            0,
            0,
            header.sequence,
            self.free_buffers,
        )
        data = push_header(refused) + self.codec.push_body(refused, Refused(reason))
        self._out.append((data, peer))

    def _downlink(
        self, session: RobotSession, header: Header, body: MapBody, arrival: Arrival, now: float
    ) -> None:
        # This runs every period (D-RSP-13). So items are unpacked, and names are held in locals.
        items = body.items
        newer = arrival is _NEWER
        if newer:
            if header.buffer & CLEAR_BUFFER:  # R-RSP-33: before the payloads
                self._buffer.clear()
            flags = frozenset([d for d, ident, values in items if values is None and ident is None])
            session.active_modules = flags & self._modules
            session.requested = flags - self._modules
        acks = []
        devices = self.model.devices
        module_of, active = self._module_of, session.active_modules
        stamp = header.timestamp
        for position, ident, values in items:
            if ident is not None:
                assert values is not None
                if self._occurrence(session, position, ident, values):
                    acks.append(Item(position, ident))  # R-RSP-26
            elif values is not None and newer:
                module = module_of[position]  # `_in_active`, inlined for speed
                if module is None or module in active:
                    found = devices[position]
                    session.motion.receive(found, values, stamp, now)
                    self._events.append(make_namedtuple(StateReceived, (found.name, values, stamp)))
        if acks:
            self._send(session, PacketType.ACK, MapBody(tuple(acks)), now)

    def _occurrence(
        self, session: RobotSession, position: int, ident: int, values: Mapping[str, Value]
    ) -> bool:
        """Take a command or memory command once (R-RSP-25); whether to acknowledge it."""
        found = self.model.devices[position]
        if not session.commands.is_new(position, ident):
            return True  # seen before: acknowledged again
        if found.kind is _K.MEMORY_COMMAND:
            if not self.free_buffers:  # R-RSP-31: neither taken nor acknowledged
                return False
            self._buffer.append(Occurrence(found, ident, dict(values)))
        else:
            self._events.append(events.OccurrenceReceived(found.name, ident, values))
        session.commands.take(position, ident)
        return True

    def _in_active(self, session: RobotSession, position: int) -> bool:
        """Not in a module, or in one the newest DOWNLINK activated (D-RSP-14)."""
        module = self._module_of[position]
        return module is None or module in session.active_modules

    def _reports(self, position: int) -> bool:
        """Requested by the newest DOWNLINK, and not in an inactive module (D-RSP-14)."""
        session = self.session
        return (
            session is not None
            and position in session.requested
            and self._in_active(session, position)
        )

    # -- sending -------------------------------------------------------------------------------

    def _set_period(self, session: RobotSession, period_ms: int, now: float) -> None:
        period = max(period_ms, self._min_period_ms) / 1000
        if period != session.beat.period:
            session.beat = Beat(period, now + period)
            session.live.period = session.motion.period = period

    def _send(self, session: RobotSession, kind: PacketType, body: Body, now: float) -> None:
        data = session.wire.build(kind, body, now, self.free_buffers, self._psk)
        self._out.append((data, session.peer))

    def _uplink(self, session: RobotSession, now: float) -> None:
        items: dict[int, Item] = {}
        states = self._states
        for position in self._reported & session.requested:
            values = states.get(position)
            if values is not None and self._in_active(session, position):
                items[position] = make_namedtuple(Item, (position, None, values))
        for occurrence in self._events_out.ride():
            position = occurrence.device.position
            items[position] = Item(position, occurrence.id, occurrence.values)
        due = self._memory_events.due(now, _any)
        for occurrence in due:
            position = occurrence.device.position
            items[position] = Item(position, occurrence.id, occurrence.values)
        if not items and not session.beat.quiet():
            return
        session.beat.sent()
        self._send(session, _UPLINK, map_body(tuple([items[p] for p in sorted(items)])), now)
        self._memory_events.sent(due, now)

    # -- silence and ending --------------------------------------------------------------------

    def _time_out(self, now: float) -> None:
        """Nothing from the peer for 10 seconds: BYE (R-RSP-22)."""
        self._bye(ByeReason.TIMEOUT, now)

    def _stop_on_loss(self, session: RobotSession) -> None:
        """The link lost: the effectors whose onLoss is zero stop (R-RSP-36)."""
        session.motion.lose_link()

    def _bye(self, reason: ByeReason, now: float) -> None:
        session = self.session
        assert session is not None
        self._send(session, PacketType.BYE, Bye(reason), now)
        self._end(events.SessionClosed(reason, by_peer=False))

    def _end(self, event: events.SessionClosed) -> None:
        self.session = None
        self._buffer.clear()
        self._events.append(event)


def _module_position(model: RobotModel, found: Device) -> int | None:
    """The position of `found`'s module.

    None when it is in no module. -1 when the model has no such device: then no DOWNLINK can
    activate it (D-RSP-14).
    """
    if found.module is None:
        return None
    owner = model.device(found.module)
    return -1 if owner is None else owner.position


def _any(found: Device) -> bool:
    """Always true: a robot's memory events start when due. It waits for no free-buffer credit."""
    return True
