"""One session of an RSP local system under test, the robot's side of it, as a case plays it
(`LocalProbe`, which `local_listener.LocalListener.accept` gives the case): the case answers the
HELLO (`welcome`, a WELCOME signed with a wrong key, or `refuse`), reads what the local system sends
(`next`, `expect`, `packets`: each datagram read by the core's codec and, in an encrypted session,
opened with the session's keys; one that cannot be read fails the case, the next time it waits,
under the rule the codec names), and sends UPLINKs, ACKs and BYE numbered, stamped and sealed by the
core's `SessionWire` (`forged`: one the local system must drop, naming another session or with a
body no robot sends). Like a robot it acknowledges each command and memory command at once
(R-RSP-26), but those of the devices in `withheld`, and memory commands while it announces no free
buffer (R-RSP-31); it gives `free` in every packet's buffer byte and, while `beating`, sends an
UPLINK with an empty Device Map every 5 periods (D-RSP-13). Every datagram both ways is in the
case's transcript. Every wait is bounded.
"""

from __future__ import annotations

import asyncio
import os
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Protocol

from rcmlconf.conformance.kept import Kept
from rcmlconf.conformance.probes.datagrams import FIRST, LAST, DatagramLog, kept_log
from rcmlconf.conformance.probes.impaired import ImpairedPath
from rcmlconf.conformance.probes.local_scenario import SCENARIO_LIFETIME
from rcmlconf.conformance.probes.rsp_datagram import (
    LAST_AT,
    SESSION_AT,
    UNSEALED,
    Datagram,
    newer,
    sequence_of,
    summary,
)
from rcmlconf.conformance.rsp_numbers import HELLO_INTERVAL, KEEPALIVE_PERIODS
from rcmlconf.conformance.transcript import Address, Transcript
from rcmlconf.conformance.verdicts import Failed, HarnessError
from rcmlconf.errors import ProtocolError
from rcmlconf.impair import ImpairedChannel
from rcmlconf.rctp.datastream.order import SequenceTracker
from rcmlconf.rsp.codec import (
    Bye,
    ByeReason,
    Encryption,
    Header,
    Hello,
    Item,
    MapBody,
    PacketType,
    Refused,
    RefusedReason,
    RspCodec,
    Welcome,
    pull_header,
    push_header,
)
from rcmlconf.rsp.codec.bodies import MAX_PERIOD_MS, Body
from rcmlconf.rsp.layout import HEADER_SIZE, MAC_SIZE, NONCE_SIZE
from rcmlconf.rsp.model import DeviceKind, RobotModel
from rcmlconf.rsp.security import Direction, Sealer, session_key
from rcmlconf.rsp.session.wire import SessionWire

#: A HELLO not repeated for this long is one its local system gave up on (D-RSP-12).
STALE = HELLO_INTERVAL + 0.1
#: How long a case listens for what must not come (scaled by the case's timeout scale).
QUIET = 0.25
#: The requirements a datagram the codec refuses breaks, when its error names none.
HEADER, LAYOUT, SEALING = "R-RSP-13", "R-RSP-16", "R-RSP-37"
#: What a local system sends (D-RSP-11).
LOCAL_TYPES = frozenset(
    {PacketType.HELLO, PacketType.DOWNLINK, PacketType.ACK, PacketType.BYE, PacketType.PERIOD}
)
_SESSION_BITS = 48


@dataclass
class Ended:
    """A session a case ended (BYE) or refused, which the local system must be done with before
    the next case can have one (`LocalListener.settled`)."""

    source: Address
    session_id: int
    #: The sequence number of the robot's BYE; None when no session was opened.
    bye: int | None
    #: When the case ended it, and its T (loop time, seconds).
    at: float
    period: float
    #: When the local system's run is over at the latest (D-RSP-24 step 5).
    deadline: float
    #: Datagrams of the session the local system sent after it had the BYE (R-RSP-22).
    went_on: int = 0
    last: float = 0.0
    #: Its own BYE came: the session is over.
    over: bool = False

    def heard(self, data: bytes, now: float) -> bool:
        """Take a datagram from the session's source; whether it ends the session (its BYE)."""
        if len(data) < HEADER_SIZE or int.from_bytes(data[SESSION_AT:LAST_AT]) != self.session_id:
            return False
        if data[4] == PacketType.BYE:
            self.over = True
            return True
        last = int.from_bytes(data[LAST_AT : LAST_AT + 2])
        # Sent after it had the BYE: it says so (R-RSP-15), or came two periods after it.
        if (self.bye is not None and newer(last, self.bye)) or now > self.at + 2 * self.period:
            self.went_on += 1
            self.last = now
        return False


class PlayedRobot(Protocol):
    """The robot the harness plays, as each of its probes needs it
    (`local_listener.LocalListener`): the model, codec and key the probe reads and seals with,
    the robot's clock and socket, and to be told when the probe's session is over."""

    model: RobotModel
    codec: RspCodec
    psk: bytes | None

    @property
    def address(self) -> Address: ...

    @property
    def now(self) -> float: ...

    def sendto(self, data: bytes, peer: Address) -> None: ...

    def released(self, probe: LocalProbe, ended: Ended) -> None: ...


class LocalProbe(DatagramLog):
    """One local system's session, from the robot the harness plays (`LocalListener.accept`)."""

    def __init__(
        self,
        listener: PlayedRobot,
        peer: Address,
        nonce: bytes,
        transcript: Transcript,
        wait: float,
    ) -> None:
        self.listener = listener
        self.model = listener.model
        self.codec = listener.codec
        self.psk = listener.psk
        self.peer = peer
        #: The client nonce of the session's HELLO.
        self.nonce = nonce
        self.transcript = transcript
        #: Seconds to wait for something that must come (the case's, scaled).
        self.wait = wait
        #: Seconds to listen for what must not come.
        self.quiet = QUIET
        #: Every datagram of the local system, in arrival order (HELLOs that came before the
        #: case too, at their own arrival time; its first and last: `kept_log`).
        self.received = kept_log()
        #: Every datagram the probe sent: (loop time, bytes) (likewise).
        self.sent: Kept[tuple[float, bytes]] = Kept(FIRST, LAST)
        self.fault: Failed | None = None
        #: hello -> open (WELCOME given) -> ended (BYE) | refused; closed with the case.
        self.state = "hello"
        self.closed = False
        #: The session's wire once WELCOME is given: numbering, stamps, sealing (D-RSP-10).
        self.wire: SessionWire | None = None
        #: T in force, seconds (WELCOME's; the model's before).
        self.period = self.model.period
        #: When WELCOME was given (loop time), None before.
        self.opened_at: float | None = None
        #: The sequence number of the robot's BYE, once sent.
        self.bye_sequence: int | None = None
        #: The free memory-command buffers every packet gives (D-RSP-19).
        self.free = self.model.command_buffers
        #: Devices (positions) whose occurrences the probe does not acknowledge.
        self.withheld: set[int] = set()
        #: Whether it sends the robot's keep-alive UPLINK (D-RSP-13).
        self.beating = True
        self._arrival = asyncio.Event()
        self._opener: Sealer | None = None
        #: What seals the robot's packets of an encrypted session, for `forged`.
        self._sealer: Sealer | None = None
        self._tracker = SequenceTracker()
        self._beat: asyncio.TimerHandle | None = None
        #: The WELCOME or REFUSED given, sent again to a repeat of the HELLO (D-RSP-12).
        self._answer = b""
        self._forward: ImpairedPath | None = None
        self.spoiled = 0

    @property
    def now(self) -> float:
        return self.listener.now

    @property
    def channel(self) -> ImpairedChannel | None:
        """The impairment's channel of what the probe sends (None without one)."""
        return self._forward.channel if self._forward is not None else None

    @property
    def session_id(self) -> int:
        return self.wire.session_id if self.wire is not None else 0

    @property
    def hellos(self) -> list[Datagram]:
        return [d for d in self.received if d.type is PacketType.HELLO]

    @property
    def hello(self) -> Datagram:
        """The session's first HELLO (the case fails if the codec could not read it)."""
        self.check()
        hellos = self.hellos
        if not hellos:
            raise HarnessError("the probe has no HELLO")
        return hellos[0]

    @property
    def encryption(self) -> Encryption:
        return self.hello.header.encryption

    # -- receiving -----------------------------------------------------------------------------

    def _arrived(self, data: bytes, at: float) -> None:
        self.transcript.packet("udp", self.peer, self.listener.address, data)
        found = self._decode(data, at)
        if found is not None:
            self.keep(found)
            early = self.now - at
            when = f" ({early * 1000:.0f} ms before the case took it)" if early > 0.001 else ""
            self.transcript.note(f"<- {summary(self.model, found.header, found.body)}{when}")
            self._handle(found)
        self._arrival.set()

    def _decode(self, data: bytes, at: float) -> Datagram | None:
        """The datagram read by the codec; a fault of the local system's (kept for `check`) if
        it cannot be."""
        try:
            header = self.codec.pull_header(data)
        except ProtocolError as error:
            self._fail(error.rule or HEADER, "the 20-byte header of D-RSP-10", data, error)
            return None
        if header.type not in LOCAL_TYPES:
            wrong = ProtocolError(f"a {header.type.name} is not the local system's to send", 4)
            self._fail(HEADER, "a packet type a local system sends (D-RSP-11)", data, wrong)
            return None
        plain = data[HEADER_SIZE:]
        if header.encryption is not Encryption.NONE and header.type not in UNSEALED:
            if self._opener is None or header.session_id != self.session_id:
                return Datagram(at, data, header, None)
            try:
                index = self._tracker.extended(header.sequence)
                plain = self._opener.open(data[:HEADER_SIZE], plain, index)
                self._tracker.see(header.sequence)
            except ProtocolError as error:
                self._fail(SEALING, "a body sealed with the session's keys", data, error)
                return None
        try:
            body = self.codec.pull_body(header, plain)
        except ProtocolError as error:
            name = header.type.name
            self._fail(error.rule or LAYOUT, f"a {name} body of D-RSP-11", data, error)
            return None
        return Datagram(at, data, header, body)

    def _handle(self, found: Datagram) -> None:
        """What a robot does at once: its last received sequence number, and ACKs (R-RSP-26)."""
        wire = self.wire
        repeated = isinstance(found.body, Hello) and found.body.client_nonce == self.nonce
        if repeated and self._answer:  # the answer to it was lost: the same again (D-RSP-12)
            self.send(self._answer, f"{self.state}: the same answer to the repeated HELLO")
            return
        if wire is None or self.state != "open" or found.type is PacketType.HELLO:
            return
        if found.header.session_id != wire.session_id:
            return
        wire.tracker.see(found.header.sequence)
        if found.type is PacketType.DOWNLINK:
            acks = [Item(i.device, i.id) for i in found.items if i.id is not None and self._acks(i)]
            if acks:
                self.ack(acks)

    def _acks(self, item: Item) -> bool:
        if item.device in self.withheld:
            return False
        kind = self.model.devices[item.device].kind
        return kind is not DeviceKind.MEMORY_COMMAND or self.free > 0  # R-RSP-31

    def after(self, found: Datagram) -> int:
        """The place in `received` just after `found`."""
        return self.received.index(found) + 1

    # -- sending -------------------------------------------------------------------------------

    def send(self, data: bytes, what: str) -> None:
        """`data`, one datagram to the local system, through the case's impairment if any."""
        if self.closed:
            return
        if self._forward is None:
            self._put(data, what)
            return
        fate = self._forward.put(data, self.peer)
        if fate:
            self.spoiled += 1
            self.transcript.note(f"-x {what} ({fate} by the impairment)")

    def _leave(self, data: bytes, _: Address, lost: int, _at: float) -> None:
        self._put(data)

    def _put(self, data: bytes, what: str = "") -> None:
        if self.closed:
            return
        self.sent.append((self.now, data))
        self.transcript.packet("udp", self.listener.address, self.peer, data)
        self.transcript.note(f"-> {what or self._line(data)}")
        self.listener.sendto(data, self.peer)

    def welcome(self, period_ms: int | None = None, *, key: bytes | None = None) -> bytes:
        """WELCOME to the HELLO, opening the session with T of `period_ms` (by default the
        HELLO's); signed with `key` instead of the pre-shared key it is a forgery (R-RSP-38):
        sent, but the probe opens no session with it."""
        hello = self.hello
        encryption = hello.header.encryption
        if encryption is not Encryption.NONE and self.psk is None:
            raise HarnessError("an encrypted session needs the robot's pre-shared key")
        body = hello.body
        assert isinstance(body, Hello)
        wire = SessionWire(self.codec, encryption, Direction.UPLINK)
        while not wire.session_id:
            wire.session_id = int.from_bytes(os.urandom(_SESSION_BITS // 8))
        wire.tracker.see(self.hellos[-1].header.sequence)
        robot_nonce = os.urandom(NONCE_SIZE)
        period = body.period_ms if period_ms is None else min(period_ms, MAX_PERIOD_MS)
        signed = encryption is not Encryption.NONE
        welcome = Welcome(self.nonce, robot_nonce, period, bytes(MAC_SIZE) if signed else b"")
        data = wire.build(PacketType.WELCOME, welcome, self.now, self.free, key or self.psk)
        forged = key is not None
        self.send(
            data, self._line(data, welcome) + (" (signed with a wrong key)" if forged else "")
        )
        if not forged:
            self._answer = data
            self.wire = wire
            self.period = period / 1000
            self.state = "open"
            self.opened_at = self.now
            if signed:
                assert self.psk is not None
                wire.secure(self.psk, self.nonce, robot_nonce)
                keys = {
                    way: session_key(self.psk, self.nonce, robot_nonce, wire.session_id, way)
                    for way in Direction
                }
                self._opener = Sealer(encryption, keys[Direction.DOWNLINK])
                self._sealer = Sealer(encryption, keys[Direction.UPLINK])
            self._arm()
        return data

    def refuse(self, reason: RefusedReason) -> bytes:
        """REFUSED to the newest HELLO: its model ID and encryption echoed (D-RSP-12)."""
        hello = self.hellos[-1].header if self.hellos else None
        model_id = hello.model_id if hello is not None else self.model.model_id
        encryption = hello.encryption if hello is not None else Encryption.NONE
        last = hello.sequence if hello is not None else 0
        header = Header(1, model_id, encryption, PacketType.REFUSED, 0, 0, 0, last, self.free)
        body = Refused(reason)
        data = push_header(header) + self.codec.push_body(header, body)
        self.send(data, summary(self.model, header, body))
        self.state = "refused"
        self._answer = data
        return data

    def packet(self, kind: PacketType, body: Body) -> bytes:
        """The session's next packet from the robot, sent."""
        data = self._wire(kind).build(kind, body, self.now, self.free, self.psk)
        self.send(data, self._line(data, body))
        return data

    def forged(
        self,
        kind: PacketType,
        body: Body,
        what: str,
        *,
        session_id: int | None = None,
        alter: Callable[[bytes], bytes] | None = None,
        via: Callable[[bytes], object] | None = None,
    ) -> bytes:
        """The session's next packet from the robot made one the local system must drop unread
        (R-RSP-18): naming `session_id`, its body's bytes changed by `alter` (before sealing, in
        an encrypted session: it authenticates, and is malformed all the same), or sent by `via`
        (from another address) rather than the probe. Sent, `what` in the transcript; the bytes
        sent."""
        wire = self._wire(kind)
        index = wire.sent
        data = wire.build(kind, body, self.now, self.free, self.psk)
        head, rest = data[:HEADER_SIZE], data[HEADER_SIZE:]
        sealer = self._sealer
        if sealer is not None:
            rest = sealer.open(head, rest, index)
        if session_id is not None:
            head = head[:SESSION_AT] + session_id.to_bytes(6) + head[LAST_AT:]
        if alter is not None:
            rest = alter(rest)
        if sealer is not None:
            rest = sealer.seal(head, rest, index)
        line = f"{what}: {self._line(head + rest)}"
        if via is None:
            self.send(head + rest, line)
        else:
            self.transcript.note(f"-> {line}")
            via(head + rest)
        return head + rest

    def _wire(self, kind: PacketType) -> SessionWire:
        if self.wire is None or self.state != "open":
            raise HarnessError(f"no open session to send a {kind.name} in")
        return self.wire

    def uplink(self, items: Iterable[Item] = ()) -> bytes:
        """An UPLINK of `items` (in any order: sorted into model order)."""
        return self.packet(PacketType.UPLINK, MapBody(tuple(sorted(items, key=lambda i: i.device))))

    def ack(self, items: Iterable[Item]) -> bytes:
        """An ACK of the occurrences `items` name (device and ID)."""
        found = tuple(sorted((Item(i.device, i.id) for i in items), key=lambda i: i.device))
        return self.packet(PacketType.ACK, MapBody(found))

    def bye(self, reason: ByeReason = ByeReason.SHUTDOWN) -> bytes:
        """BYE: the session ends (R-RSP-22). Sent again while the impairment spoils it (the
        local system answers none, and a case ending the session means it); the last sent."""
        sent: list[bytes] = []
        self.send_intact(lambda: sent.append(self.packet(PacketType.BYE, Bye(reason))))
        self.state = "ended"
        self.bye_sequence = sequence_of(sent[-1])
        return sent[-1]

    def _line(self, data: bytes, body: Body | None = None) -> str:
        """A datagram this probe sends, for the transcript (its body decoded if not given; the
        impairment may have corrupted it)."""
        try:
            header = pull_header(data)
            if body is None and (header.encryption is Encryption.NONE or header.type in UNSEALED):
                body = self.codec.pull_body(header, data[HEADER_SIZE:])
        except ProtocolError as error:
            return f"{len(data)} bytes {data[:24].hex()} ({error.reason})"
        return summary(self.model, header, body)

    def _arm(self) -> None:
        if self._beat is not None:
            self._beat.cancel()
        self._beat = asyncio.get_running_loop().call_later(
            KEEPALIVE_PERIODS * self.period, self._keep_alive
        )

    def _keep_alive(self) -> None:
        self._beat = None
        if self.state != "open" or self.closed:
            return
        if self.beating:
            self.uplink()
        self._arm()

    # -- the end -------------------------------------------------------------------------------

    def close(self) -> None:
        """The run ends: BYE to an open session, REFUSED (busy) to a HELLO left unanswered."""
        if self.closed:
            return
        self.noted_left_out()
        if self._forward is not None:
            # What the impairment holds goes now, and the last word straight to the socket: an
            # impairment must not leave the local system in a session or waiting on a HELLO.
            self._forward.close(flush=True)
            self._forward = None
        if self.state == "open" and self.wire is not None:
            bye = Bye(ByeReason.CLOSED)
            data = self.wire.build(PacketType.BYE, bye, self.now, self.free, self.psk)
            self.send(data, "BYE (the case ends)")
            self.bye_sequence = sequence_of(data)
        elif self.state == "hello" and self.hellos:
            self.refuse(RefusedReason.BUSY)
        ended = self._record()
        self.closed = True
        if self._beat is not None:
            self._beat.cancel()
            self._beat = None
        self.listener.released(self, ended)

    def _record(self) -> Ended:
        """The session as the case leaves it. The local system's run is over 10 s after WELCOME
        at the latest (D-RSP-24 step 5), or at once after a REFUSED or a HELLO left unanswered."""
        opened = self.opened_at
        deadline = (opened + SCENARIO_LIFETIME if opened is not None else self.now) + STALE
        return Ended(self.peer, self.session_id, self.bye_sequence, self.now, self.period, deadline)
