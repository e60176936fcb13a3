"""Where RSP local systems under test send (`--role local --listen [HOST:]PORT --model M`): the
harness plays a robot of model M on one UDP socket, as Autobahn's fuzzing server plays the peer of
the clients it tests. A local system under test runs the conformance scenario of D-RSP-24 each
time it is started; each local-system case takes the next *new* session: the next HELLO whose
nonce no case has taken yet, from whatever source (`LocalListener.accept`). A HELLO that came
before a case asked is kept with its repeats, so the case sees them all; one its local system has
given up on (no repeat for longer than D-RSP-12's interval) is forgotten. The embedded reference
has a `summon` that starts one run of the scenario (`local_scenario.reference_local`) whenever a
case waits.

A case's session ends with the case (BYE, or REFUSED to a HELLO left unanswered). A local system
under test runs one session at a time (D-RSP-24), so the next case can have one only once the
local system is done with that one: `LocalListener.settled`, which the runner awaits before a local
case's clock starts (as a robot case waits for a free robot), waits until it is: a new HELLO came,
or the old session's own BYE, or the old run is over by D-RSP-24 step 5 (10 s after WELCOME). A
local system that goes on with a session after the robot's BYE breaks R-RSP-22
(rsp/local/bye-ends fails it); it costs the cases after it time, not their verdicts. What the old
session sent after the BYE is noted in the transcript of the case that waited.
"""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import Awaitable, Callable
from dataclasses import dataclass, field

from rcmlconf.conformance.kept import Kept
from rcmlconf.conformance.probes.impaired import ImpairedPath
from rcmlconf.conformance.probes.inbound import Inbound
from rcmlconf.conformance.probes.local_probe import STALE, Ended, LocalProbe
from rcmlconf.conformance.rsp_numbers import HELLO_INTERVAL, HELLO_RETRIES
from rcmlconf.conformance.transcript import Address, Transcript
from rcmlconf.conformance.verdicts import Inconclusive
from rcmlconf.errors import ProtocolError
from rcmlconf.impair import ImpairedChannel, Impairment
from rcmlconf.rsp.codec import Encryption, PacketType, RspCodec
from rcmlconf.rsp.layout import HEADER_SIZE, NONCE_SIZE
from rcmlconf.rsp.model import RobotModel

Summon = Callable[[Address], Awaitable[None]]
#: While the listener is younger than a local system's HELLO phase, a repeated HELLO (its sequence
#: and timestamp past a first one's) of a new session is of a session begun before anyone
#: listened: it is ignored, and the local system gives up on it and starts a new one.
WARM_UP = HELLO_INTERVAL * (HELLO_RETRIES + 1) + 0.25
_NONCE_AT = HEADER_SIZE
#: New sessions' HELLOs waiting for a case, at most: past them the oldest is forgotten (HELLOs
#: with ever new nonces are a flood, not local systems waiting).
PENDING = 64
#: Datagrams of one waiting session kept, from its first and from its last: its HELLO and the
#: repeats D-RSP-12 allows are far fewer.
REPEATS = 64


def _repeated(data: bytes) -> bool:
    """A HELLO that says it is a repeat: neither its session's first packet nor sent at once."""
    stamp = int.from_bytes(data[7:11])
    return int.from_bytes(data[5:7]) != 0 and stamp >= HELLO_INTERVAL * 500


def _is_hello(data: bytes) -> bool:
    return len(data) > 4 and data[4] == PacketType.HELLO


@dataclass
class _Pending:
    """A HELLO no case has taken yet, with its repeats: (loop time, bytes)."""

    source: Address
    nonce: bytes
    datagrams: Kept[tuple[float, bytes]] = field(default_factory=lambda: Kept(REPEATS, REPEATS))

    @property
    def last(self) -> float:
        return self.datagrams[-1][0]


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
        self._ended: list[Ended] = []
        #: Set by a HELLO, or by the BYE of an ended session: what `accept` and `settled` await.
        self._hello = asyncio.Event()
        self._tasks: set[asyncio.Task[None]] = set()

    async def start(self, host: str, port: int) -> None:
        transport, _ = await self._loop.create_datagram_endpoint(
            # An error (ICMP unreachable: a local system that has gone) is dropped: nothing waits.
            lambda: Inbound(self._arrived),
            local_addr=(host, port),
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

    def _arrived(self, data: bytes, source: Address, at: float) -> None:
        probe = self._bound.get(source)
        if not _is_hello(data) or len(data) < _NONCE_AT + NONCE_SIZE:
            if probe is not None:
                probe._arrived(data, at)
                return
            # Else of a session no case holds: one that ended, which the local system may go on
            # with (R-RSP-22). Nobody answers; `settled` hears it.
            for ended in self._ended:
                if ended.source == source and ended.heard(data, at):
                    self._hello.set()
            return
        nonce = data[_NONCE_AT : _NONCE_AT + NONCE_SIZE]
        if probe is not None and probe.nonce == nonce:
            probe._arrived(data, at)
            return
        key = (source, nonce)
        if key in self._taken:
            return
        entry = self._pending.get(key)
        if entry is None:
            if _repeated(data) and at - self._started < WARM_UP:
                return
            if len(self._pending) >= PENDING:
                del self._pending[next(iter(self._pending))]
            entry = self._pending[key] = _Pending(source, nonce)
            self._ever_heard = True
        entry.datagrams.append((at, data))
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

    def released(self, probe: LocalProbe, ended: Ended) -> None:
        """A case is done with `probe` (`LocalProbe.close`): its session as the case left it is
        noted for the next case (`_went_on`), and its source's datagrams go to no probe."""
        self._ended.append(ended)
        if self._bound.get(probe.peer) is probe:
            del self._bound[probe.peer]

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
