"""Where RSP local systems under test send (`--role local --listen [HOST:]PORT --model M`): the
harness plays a robot of model M on one UDP socket, as Autobahn's fuzzing server plays the peer of
the clients it tests. A local system under test runs the conformance scenario of D-RSP-24 each
time it is started; each local-system case takes the next *new* session: the next HELLO whose
nonce no case has taken yet, from whatever source (`LocalListener.accept`). A HELLO that came
before a case asked is kept with its repeats, so the case sees them all; one its local system has
given up on (no repeat for longer than D-RSP-12's interval) is forgotten. The embedded reference
has a `summon` that starts one run of the scenario (`reference_local`) whenever a case waits.

A case's session ends with the case (BYE, or REFUSED to a HELLO left unanswered). A local system
under test runs one session at a time (D-RSP-24), so the next case can have one only once the
local system is done with that one: `LocalListener.settled`, which the runner awaits before a local
case's clock starts (as a robot case waits for a free robot), waits until it is: a new HELLO came,
or the old session's own BYE, or the old run is over by D-RSP-24 step 5 (10 s after WELCOME). A
local system that goes on with a session after the robot's BYE breaks R-RSP-22
(rsp/local/bye-ends fails it); it costs the cases after it time, not their verdicts. What the old
session sent after the BYE is noted in the transcript of the case that waited.

A `LocalProbe` is one such session, the robot's side of it: the case answers the HELLO (`welcome`,
a WELCOME signed with a wrong key, or `refuse`), reads what the local system sends (`next`,
`expect`, `packets`: each datagram read by the core's codec and, in an encrypted session, opened
with the session's keys; one that cannot be read fails the case, the next time it waits, under the
rule the codec names), and sends UPLINKs, ACKs and BYE numbered, stamped and sealed by the core's
`SessionWire` (`forged`: one the local system must drop, naming another session or with a body no
robot sends). Like a robot it acknowledges each command and memory command at once (R-RSP-26),
but those of the devices in `withheld`, and memory commands while it announces no free buffer
(R-RSP-31); it gives `free` in every packet's buffer byte and, while `beating`, sends an UPLINK with
an empty Device Map every 5 periods (D-RSP-13). Every datagram both ways is in the case's
transcript. Every wait is bounded.
"""

from __future__ import annotations

import asyncio
import contextlib
import os
from collections.abc import Awaitable, Callable, Iterable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from rcmlconf.conformance.probes.datagrams import DatagramLog
from rcmlconf.conformance.probes.impaired import ImpairedPath
from rcmlconf.conformance.probes.rsp import Datagram, newer, sequence_of, summary
from rcmlconf.conformance.rsp_numbers import HELLO_INTERVAL, HELLO_RETRIES, KEEPALIVE_PERIODS
from rcmlconf.conformance.transcript import Address, Transcript
from rcmlconf.conformance.verdicts import Failed, HarnessError, Inconclusive
from rcmlconf.errors import ProtocolError
from rcmlconf.impair import ImpairedChannel, Impairment
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
from rcmlconf.rsp.model import Device, DeviceKind, RobotModel
from rcmlconf.rsp.security import Direction, Sealer, session_key
from rcmlconf.rsp.session.wire import SessionWire
from rcmlconf.values import Value

if TYPE_CHECKING:
    from rcmlconf.reference.rsp.simulacrum import Simulacrum

Summon = Callable[[Address], Awaitable[None]]
#: A HELLO not repeated for this long is one its local system gave up on (D-RSP-12).
STALE = HELLO_INTERVAL + 0.1
#: While the listener is younger than a local system's HELLO phase, a repeated HELLO (its sequence
#: and timestamp past a first one's) of a new session is of a session begun before anyone
#: listened: it is ignored, and the local system gives up on it and starts a new one.
WARM_UP = HELLO_INTERVAL * (HELLO_RETRIES + 1) + 0.25
#: How long a case listens for what must not come (scaled by the case's timeout scale).
QUIET = 0.25
#: The requirements a datagram the codec refuses breaks, when its error names none.
HEADER, LAYOUT, SEALING = "R-RSP-13", "R-RSP-16", "R-RSP-37"
#: What a local system sends (D-RSP-11).
LOCAL_TYPES = frozenset(
    {PacketType.HELLO, PacketType.DOWNLINK, PacketType.ACK, PacketType.BYE, PacketType.PERIOD}
)
_SEALED_NEVER = frozenset({PacketType.HELLO, PacketType.WELCOME, PacketType.REFUSED})
_SESSION_BITS = 48
_NONCE_AT = HEADER_SIZE
_SESSION_AT, _LAST_AT = 11, 17


def _repeated(data: bytes) -> bool:
    """A HELLO that says it is a repeat: neither its session's first packet nor sent at once."""
    stamp = int.from_bytes(data[7:11])
    return int.from_bytes(data[5:7]) != 0 and stamp >= HELLO_INTERVAL * 500


def _is_hello(data: bytes) -> bool:
    return len(data) > 4 and data[4] == PacketType.HELLO


@dataclass
class _Ended:
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
        if len(data) < HEADER_SIZE or int.from_bytes(data[_SESSION_AT:_LAST_AT]) != self.session_id:
            return False
        if data[4] == PacketType.BYE:
            self.over = True
            return True
        last = int.from_bytes(data[_LAST_AT : _LAST_AT + 2])
        # Sent after it had the BYE: it says so (R-RSP-15), or came two periods after it.
        if (self.bye is not None and newer(last, self.bye)) or now > self.at + 2 * self.period:
            self.went_on += 1
            self.last = now
        return False


@dataclass
class _Pending:
    """A HELLO no case has taken yet, with its repeats: (loop time, bytes)."""

    source: Address
    nonce: bytes
    datagrams: list[tuple[float, bytes]] = field(default_factory=list)

    @property
    def last(self) -> float:
        return self.datagrams[-1][0]


class _Socket(asyncio.DatagramProtocol):
    def __init__(self, listener: LocalListener) -> None:
        self.listener = listener

    def datagram_received(self, data: bytes, addr: tuple[str | int, ...]) -> None:
        self.listener._arrived(data, (str(addr[0]), int(addr[1])))

    def error_received(self, exc: Exception) -> None:
        pass  # ICMP unreachable: a local system that has gone; nothing waits for it


class LocalListener:
    """The harness's robot socket: one local-system session a case (`accept`)."""

    def __init__(
        self,
        model: RobotModel,
        psk: bytes | None = None,
        summon: Summon | None = None,
        stop: Callable[[str], list[str]] | None = None,
        on_wait: Callable[[], None] | None = None,
    ) -> None:
        self.model = model
        self.codec = RspCodec(model)
        #: The robot's pre-shared key (D-RSP-21): without it encrypted sessions are refused.
        self.psk = psk
        #: Starts a local system sending to the harness (the embedded reference, --client-command);
        #: `stop` stops it, by the address it was given, when its case ends.
        self._summon = summon
        self._stop = stop
        #: Told of each case that waits for a local system it does not start itself.
        self._on_wait = on_wait
        self._ever_heard = False
        self._given_up = False
        #: The runs of local cases planned (the runner's), for the waiting line.
        self.runs = 0
        self._loop = asyncio.get_running_loop()
        self._transport: asyncio.DatagramTransport | None = None
        self._started = 0.0
        self._pending: dict[tuple[Address, bytes], _Pending] = {}
        self._taken: set[tuple[Address, bytes]] = set()
        #: The newest probe of each source: where its datagrams but new HELLOs go.
        self._bound: dict[Address, LocalProbe] = {}
        #: The sessions cases ended since the last `accept` (`settled`).
        self._ended: list[_Ended] = []
        #: Set by a HELLO, or by the BYE of an ended session: what `accept` and `settled` await.
        self._hello = asyncio.Event()
        self._tasks: set[asyncio.Task[None]] = set()

    async def start(self, host: str, port: int) -> None:
        transport, _ = await self._loop.create_datagram_endpoint(
            lambda: _Socket(self), local_addr=(host, port)
        )
        self._transport = transport
        self._started = self._loop.time()

    @property
    def side_by_side(self) -> bool:
        """Whether local cases may run at once: each summons a local system of its own, on a
        port of its own, which the listener tells apart by source address (the embedded
        reference; a --client-command is started one at a time, at the one address)."""
        return self._summon is not None and self._stop is None

    @property
    def address(self) -> Address:
        assert self._transport is not None, "start() first"
        host, port = self._transport.get_extra_info("sockname")[:2]
        return str(host), int(port)

    @property
    def now(self) -> float:
        return self._loop.time()

    def sendto(self, data: bytes, peer: Address) -> None:
        if self._transport is not None and not self._transport.is_closing():
            self._transport.sendto(data, peer)

    def _arrived(self, data: bytes, source: Address) -> None:
        now = self.now
        probe = self._bound.get(source)
        if not _is_hello(data) or len(data) < _NONCE_AT + NONCE_SIZE:
            if probe is not None:
                probe._arrived(data, now)
                return
            # Else of a session no case holds: one that ended, which the local system may go on
            # with (R-RSP-22). Nobody answers; `settled` hears it.
            for ended in self._ended:
                if ended.source == source and ended.heard(data, now):
                    self._hello.set()
            return
        nonce = data[_NONCE_AT : _NONCE_AT + NONCE_SIZE]
        if probe is not None and probe.nonce == nonce:
            probe._arrived(data, now)
            return
        key = (source, nonce)
        if key in self._taken:
            return
        entry = self._pending.get(key)
        if entry is None:
            if _repeated(data) and now - self._started < WARM_UP:
                return
            entry = self._pending[key] = _Pending(source, nonce)
            self._ever_heard = True
        entry.datagrams.append((now, data))
        self._hello.set()

    def _next_live(self, sealed: bool = False) -> _Pending | None:
        """The oldest new session's HELLO still fresh (`sealed`: one asking for encryption)."""
        for key, entry in list(self._pending.items()):
            if self.now - entry.last > STALE:
                del self._pending[key]
                continue
            if not sealed or self._sealed(entry):
                return entry
        return None

    def _sealed(self, entry: _Pending) -> bool:
        with contextlib.suppress(ProtocolError):
            return self.codec.pull_header(entry.datagrams[0][1]).encryption is not Encryption.NONE
        return False

    async def arrival(self, wait: float) -> str | None:
        """Before a local case's clock starts: a new session's HELLO, from a local system
        started for the case if the harness starts them, waited for up to `wait`
        (--connect-timeout). None once one came; else why not. After a case in which no local
        system of the run had ever sent a HELLO, the rest give up at once."""
        if self._next_live() is not None:
            return None
        host, port = self.address
        if self._given_up:
            return f"no local system has sent a HELLO to {host}:{port} (the first case waited)"
        summoned: asyncio.Task[None] | None = None
        if self._summon is not None:
            summoned = asyncio.ensure_future(self._summon((host, port)))
            self._tasks.add(summoned)
            summoned.add_done_callback(self._tasks.discard)
        elif self._on_wait is not None:
            self._on_wait()
        deadline = self.now + wait
        while self._next_live() is None:
            remaining = deadline - self.now
            summon = self._summon
            if summoned is not None and summoned.done() and self.side_by_side and remaining > 0:
                # Its HELLO went to a case beside this one (any case takes any new session):
                # another local system for this one.
                assert summon is not None  # side_by_side: the harness summons them
                summoned = asyncio.ensure_future(summon((host, port)))
                self._tasks.add(summoned)
                summoned.add_done_callback(self._tasks.discard)
            if remaining <= 0 or (summoned is not None and summoned.done()):
                self._given_up = not self._ever_heard
                if summoned is not None and summoned.done():
                    return f"the local system started for {host}:{port} ended before a HELLO"
                return f"no local system sent a HELLO to {host}:{port} within {wait:g} s"
            self._hello.clear()
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(self._hello.wait(), min(remaining, 0.25))
        return None

    def finish(self) -> list[str]:
        """The local system started for the case ending is stopped if it still runs: how it
        ran, for the case's report."""
        host, port = self.address
        return self._stop(f"{host}:{port}") if self._stop is not None else []

    async def settled(self) -> None:
        """Until the local system under test is done with the sessions the cases before ended:
        it sent a new HELLO, or the BYE of each, or its run is over by D-RSP-24 step 5. Bounded
        by that step (a run ends 10 s after WELCOME). Without a wait when the harness summons a
        new local system for each case (the embedded reference)."""
        if self._summon is not None:
            return
        busy = [e for e in self._ended if not e.over]
        while busy and self._next_live() is None:
            remaining = max(e.deadline for e in busy) - self.now
            if remaining <= 0:
                return
            self._hello.clear()
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(self._hello.wait(), remaining)
            busy = [e for e in busy if not e.over]

    def _ending(self, ended: _Ended) -> None:
        self._ended.append(ended)

    def _went_on(self, transcript: Transcript) -> None:
        """Note what the sessions the cases before ended sent after their BYE (R-RSP-22)."""
        for ended in self._ended:
            if ended.went_on:
                host, port = ended.source
                transcript.note(
                    f"the local system at {host}:{port} went on with session"
                    f" {ended.session_id:#x} after the robot's BYE (R-RSP-22): {ended.went_on}"
                    f" datagrams, the last {ended.last - ended.at:.2f} s after it; this case"
                    f" began when it was done with it, {self.now - ended.at:.2f} s after the BYE"
                )
        self._ended.clear()

    async def accept(
        self,
        transcript: Transcript,
        wait: float,
        *,
        summon: bool = True,
        sealed: bool = False,
        impairment: Impairment | None = None,
        seed: int = 0,
    ) -> LocalProbe:
        """The next new session's HELLO, as a probe; `summon` starts a local system (the embedded
        reference) when none is waiting; `sealed` takes only a HELLO asking for encryption.
        Inconclusive if no HELLO comes within `wait`. What the probe sends goes through
        `impairment` (seeded with `seed`)."""
        deadline = self.now + wait
        summoned = not summon or self._summon is None
        while (entry := self._next_live(sealed)) is None:
            if not summoned and self._summon is not None:
                task = asyncio.ensure_future(self._summon(("127.0.0.1", self.address[1])))
                self._tasks.add(task)
                task.add_done_callback(self._tasks.discard)
                summoned = True
            remaining = deadline - self.now
            if remaining <= 0:
                host, port = self.address
                raise Inconclusive(
                    f"no local system sent a HELLO to {host}:{port} within {wait:g} s"
                )
            self._hello.clear()
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(self._hello.wait(), remaining)
        key = (entry.source, entry.nonce)
        del self._pending[key]
        self._taken.add(key)
        probe = LocalProbe(self, entry.source, entry.nonce, transcript, wait)
        if impairment is not None and not impairment.is_none:
            channel = ImpairedChannel(impairment, seed)
            probe._forward = ImpairedPath(channel, probe._leave, asyncio.get_running_loop())
        self._bound[entry.source] = probe
        self._went_on(transcript)
        host, port = entry.source
        transcript.note(f"a local system at {host}:{port} opens a session (nonce {key[1].hex()})")
        for at, data in entry.datagrams:
            probe._arrived(data, at)
        return probe

    def _unbind(self, probe: LocalProbe) -> None:
        if self._bound.get(probe.peer) is probe:
            del self._bound[probe.peer]

    async def close(self) -> None:
        for task in list(self._tasks):
            task.cancel()
        for task in list(self._tasks):
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await task
        for probe in list(self._bound.values()):
            probe.close()
        if self._transport is not None:
            self._transport.close()


class LocalProbe(DatagramLog):
    """One local system's session, from the robot the harness plays (`LocalListener.accept`)."""

    def __init__(
        self,
        listener: LocalListener,
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
        #: case too, at their own arrival time).
        self.received: list[Datagram] = []
        #: Every datagram the probe sent: (loop time, bytes).
        self.sent: list[tuple[float, bytes]] = []
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
            self.received.append(found)
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
        if header.encryption is not Encryption.NONE and header.type not in _SEALED_NEVER:
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

    def _fail(self, rule: str, expected: str, data: bytes, error: ProtocolError) -> None:
        actual = f"{error.reason} at byte {error.offset} of {data[:32].hex()}"
        self.transcript.note(f"<- {len(data)} bytes the codec refuses: {actual}")
        if self.fault is None:
            self.fault = Failed(rule, expected, actual)

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

    def _leave(self, data: bytes, _: Address, lost: int) -> None:
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
            head = head[:_SESSION_AT] + session_id.to_bytes(6) + head[_LAST_AT:]
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
            if body is None and (
                header.encryption is Encryption.NONE or header.type in _SEALED_NEVER
            ):
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
        self.listener._ending(self._record())
        self.closed = True
        if self._beat is not None:
            self._beat.cancel()
            self._beat = None
        self.listener._unbind(self)

    def _record(self) -> _Ended:
        """The session as the case leaves it. The local system's run is over 10 s after WELCOME
        at the latest (D-RSP-24 step 5), or at once after a REFUSED or a HELLO left unanswered."""
        opened = self.opened_at
        deadline = (opened + SCENARIO_LIFETIME if opened is not None else self.now) + STALE
        return _Ended(
            self.peer, self.session_id, self.bye_sequence, self.now, self.period, deadline
        )


# -- the scenario (D-RSP-24) ----------------------------------------------------------------------

#: D-RSP-24 step 5: a run ends this long after WELCOME at the latest.
SCENARIO_LIFETIME = 10.0
#: The kinds the scenario requests (step 2) and stops requesting (step 4).
REQUESTED = (DeviceKind.SENSOR, DeviceKind.MONITOR, DeviceKind.EVENT, DeviceKind.MEMORY_EVENT)


def zeros(device: Device) -> dict[str, Value]:
    """Every field of `device` at D-RSP-20's zero value: what the scenario writes and issues."""
    return {f.name: f.zero() for f in device.fields}


def first_of(model: RobotModel, kind: DeviceKind) -> Device | None:
    return next((d for d in model.devices if d.kind is kind), None)


async def reference_local(model: RobotModel, psk: bytes | None, robot: Address) -> None:
    """One run of D-RSP-24's scenario by the reference simulacrum against the robot at `robot`:
    unencrypted first, then each AEAD while the robot refuses with reason 2 and `psk` is known."""
    from rcmlconf.reference.rsp.simulacrum import NoSession, Simulacrum
    from rcmlconf.rsp.session import events

    ladder = [Encryption.NONE]
    if psk is not None:
        ladder += [Encryption.AES_256_GCM, Encryption.CHACHA20_POLY1305]
    for encryption in ladder:
        key = psk if encryption is not Encryption.NONE else None
        simulacrum = Simulacrum(model, robot, encryption=encryption, psk=key)
        try:
            opened = await simulacrum.open()
        except NoSession:
            refused = simulacrum.closed
            if (
                isinstance(refused, events.SessionRefused)
                and refused.reason is RefusedReason.ENCRYPTION_NOT_OFFERED
            ):
                continue
            return
        try:
            await _use(simulacrum, opened.period)
        finally:
            await simulacrum.aclose()
        return


async def _use(simulacrum: Simulacrum, period: float) -> None:
    """Steps 2 to 5 of D-RSP-24 on an open session."""
    model = simulacrum.model
    for device in model.devices:
        if device.kind is DeviceKind.EFFECTOR:
            simulacrum.write(device.name, zeros(device))
        elif device.kind is DeviceKind.MODULE or device.kind in REQUESTED:
            simulacrum.set_active(device.name, True)
    command = first_of(model, DeviceKind.COMMAND)
    memory = first_of(model, DeviceKind.MEMORY_COMMAND)
    if command is not None:
        simulacrum.issue(command.name, zeros(command))
    if memory is not None:
        for _ in range(model.command_buffers + 1):
            simulacrum.issue(memory.name, zeros(memory))
    in_force = [period]

    def echo(_: object) -> None:
        if command is not None:
            simulacrum.issue(command.name, zeros(command))

    def idle(_: object) -> None:
        for device in model.devices:
            if device.kind in (DeviceKind.MODULE, DeviceKind.EFFECTOR, *REQUESTED):
                simulacrum.set_active(device.name, False)
        in_force[0] = min(2 * in_force[0], MAX_PERIOD_MS / 1000)
        simulacrum.set_period(in_force[0])

    for device in model.devices:
        if device.kind is DeviceKind.EVENT:
            simulacrum.listen(device.name, echo)
        elif device.kind is DeviceKind.MEMORY_EVENT:
            simulacrum.listen(device.name, idle)
    loop = asyncio.get_running_loop()
    deadline = loop.time() + SCENARIO_LIFETIME
    while simulacrum.closed is None and loop.time() < deadline:
        await asyncio.sleep(0.01)
