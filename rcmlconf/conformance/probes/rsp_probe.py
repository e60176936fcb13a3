"""An RSP local system as a case drives it, over real UDP on 127.0.0.1 (specs/rsp.md).

A probe is one UDP socket talking to one robot. It can run the core's sans-IO `LocalEndpoint`
(`open_session`: the session a well-behaved local system keeps, with its DOWNLINK every T, its
retransmissions and ACKs), and it can send datagrams the case builds by hand
(`rsp_raw.hand_driven`, a `RawSession`, whose packets are numbered, stamped and sealed by the
core's `SessionWire` and may then be altered byte by byte, or `send` of any bytes at all). Both
at once: every datagram the robot sends is decoded with the core's codec and kept in `received`,
whoever asked for it.

Every datagram sent and received is in the case's transcript (a one-line summary and the bytes).
A robot datagram the codec cannot read fails the case with the requirement of the layout it breaks
(R-RSP-13 for the header, R-RSP-16 and R-RSP-17 for a body, R-RSP-37 for a sealed body that does
not open), the next time the case waits on the probe. Every wait is bounded.

An `impairment` of the case (rcmlconf.impair) is applied inside the probe: what it sends goes
through a forward channel before the socket, what the socket receives through a backward one
before the endpoint. The transcript and `received` show the socket's side.
"""

from __future__ import annotations

import asyncio
import contextlib
import os
from collections.abc import Callable, Mapping
from typing import Protocol, cast

from rcmlconf.conformance.context import Context
from rcmlconf.conformance.kept import Kept
from rcmlconf.conformance.probes.datagrams import FIRST, LAST, DatagramLog, kept_log
from rcmlconf.conformance.probes.impaired import ImpairedPath
from rcmlconf.conformance.probes.inbound import Inbound
from rcmlconf.conformance.probes.rsp_datagram import (
    HEADER_LAYOUT,
    MODEL_AT,
    UNSEALED,
    VERSION_AT,
    Datagram,
    summary,
)
from rcmlconf.conformance.transcript import Address, Transcript
from rcmlconf.conformance.verdicts import Failed, HarnessError, Inconclusive, NotApplicable
from rcmlconf.errors import EncodeError, ProtocolError
from rcmlconf.impair import ImpairedChannel, Impairment, derive_seed
from rcmlconf.rctp.datastream.order import SequenceTracker
from rcmlconf.reference.rsp.simulacrum import session_end
from rcmlconf.rsp.codec import (
    Encryption,
    Header,
    MapBody,
    PacketType,
    Refused,
    RefusedReason,
    RspCodec,
    Welcome,
    pull_header,
)
from rcmlconf.rsp.codec.bodies import Body
from rcmlconf.rsp.layout import HEADER_SIZE, NONCE_SIZE
from rcmlconf.rsp.model import RobotModel
from rcmlconf.rsp.security import Direction, Sealer, session_key
from rcmlconf.rsp.session import events
from rcmlconf.rsp.session.local import LocalEndpoint
from rcmlconf.values import Value

#: The requirement a robot datagram the codec refuses breaks, when its error names none.
LAYOUT = "R-RSP-16"
#: A sealed body that does not open with the session's keys (D-RSP-21).
SEALING = "R-RSP-37"
#: How long a case listens for something that must not come (an answer to a dropped packet):
#: a robot acknowledges at once (D-RSP-17), so a dozen periods is ample.
QUIET = 0.25


class _Opener:
    """The uplink side of one encrypted session, to read what the robot seals (D-RSP-21)."""

    def __init__(self, sealer: Sealer) -> None:
        self.sealer = sealer
        self.tracker = SequenceTracker()

    def open(self, data: bytes, sequence: int) -> bytes:
        index = self.tracker.extended(sequence)
        plain = self.sealer.open(data[:HEADER_SIZE], data[HEADER_SIZE:], index)
        self.tracker.see(sequence)
        return plain


class HandDriven(Protocol):
    """A session a case drives packet by packet on a probe's socket (`rsp_raw.RawSession`), as
    the probe serves it: told each WELCOME it reads, asked for the BYE that ends it with the
    case."""

    @property
    def nonce(self) -> bytes: ...

    def welcomed(self, found: Datagram) -> None: ...

    def closing_bye(self) -> bytes | None: ...


class RspProbe(DatagramLog):
    """One local system's socket towards one robot (use `open_probe`)."""

    def __init__(
        self,
        model: RobotModel,
        robot: Address,
        transcript: Transcript,
        wait: float,
        psk: bytes | None,
        impairment: Impairment | None = None,
        seed: int = 0,
        name: str = "",
    ) -> None:
        self.model = model
        self.codec = RspCodec(model)
        self.robot = robot
        self.transcript = transcript
        #: Seconds to wait for an answer (the case's, scaled).
        self.wait = wait
        #: Seconds to listen for what must not come (QUIET, the case's timeout scale applied).
        self.quiet = QUIET
        self.psk = psk
        self.name = name
        self.local: Address = ("127.0.0.1", 0)
        self._transport: asyncio.DatagramTransport | None = None
        self._loop = asyncio.get_running_loop()
        #: Every datagram from the robot, in arrival order (its first and last: `kept_log`).
        self.received = kept_log()
        #: Every datagram this probe put on the wire: (loop time, bytes) (likewise).
        self.sent: Kept[tuple[float, bytes]] = Kept(FIRST, LAST)
        self._arrival = asyncio.Event()
        self.fault: Failed | None = None
        #: Client nonces of this probe's HELLOs: WELCOMEs to them give the keys to read with.
        self._nonces: set[bytes] = set()
        self._openers: dict[int, _Opener] = {}
        #: Sessions the case drives by hand on this probe's socket (`adopt`), for close().
        self.raw_sessions: list[HandDriven] = []
        # The endpoint, its events and the newest state of each device.
        self.endpoint: LocalEndpoint | None = None
        self.events: Kept[tuple[float, events.Event]] = Kept(FIRST, LAST)
        self.states: dict[str, tuple[float, Mapping[str, Value]]] = {}
        self._event = asyncio.Event()
        #: While muted, the endpoint's datagrams are not sent (the local system falls silent).
        self.muted = False
        #: Applied to the endpoint's next datagrams, one each, before they are sent.
        self._mutations: list[Callable[[bytes], bytes | None]] = []
        self._timer: asyncio.TimerHandle | None = None
        self._timer_at: float | None = None
        self._forward: ImpairedPath | None = None
        self._backward: ImpairedChannel | None = None
        #: Datagrams sent of which the impairment let no intact copy through (lost, corrupted).
        self.spoiled = 0
        if impairment is not None and not impairment.is_none:
            forward = ImpairedChannel(impairment, derive_seed(seed, name, "forward"))
            self._forward = ImpairedPath(forward, self._leave, self._loop)
            self._backward = ImpairedChannel(impairment, derive_seed(seed, name, "backward"))
        self.closed = False

    async def _bind(self) -> None:
        try:
            transport, _ = await self._loop.create_datagram_endpoint(
                lambda: Inbound(self._arrived, self._error), local_addr=("127.0.0.1", 0)
            )
        except OSError as error:
            raise HarnessError(f"cannot open a UDP socket: {error}") from None
        self._transport = transport
        host, port = transport.get_extra_info("sockname")[:2]
        self.local = (str(host), int(port))
        robot = f"{self.robot[0]}:{self.robot[1]}"
        self.transcript.note(f"{self._who}UDP {self.local[0]}:{self.local[1]} -> robot {robot}")

    @property
    def channels(self) -> tuple[ImpairedChannel | None, ImpairedChannel | None]:
        """The impairment's channels, forward and backward (None without one), for their counts."""
        forward = self._forward.channel if self._forward is not None else None
        return forward, self._backward

    @property
    def _who(self) -> str:
        return f"[{self.name}] " if self.name else ""

    @property
    def now(self) -> float:
        return self._loop.time()

    # -- sending -------------------------------------------------------------------------------

    def send(self, data: bytes, what: str = "") -> None:
        """`data` exactly as given, one datagram, through the impairment if the case has one."""
        if self._forward is None:
            self._put(data, what)
            return
        fate = self._forward.put(data, self.robot)
        if fate:
            self.spoiled += 1
            line = what or self._describe(data)
            self.transcript.note(f"{self._who}-x {line} ({fate} by the impairment)")

    def _leave(self, data: bytes, _: Address, lost: int, _at: float) -> None:
        self._put(data)

    def _put(self, data: bytes, what: str = "") -> None:
        if self._transport is None or self._transport.is_closing():
            return
        self.sent.append((self.now, data))
        self.transcript.packet("udp", self.local, self.robot, data)
        self.transcript.note(f"{self._who}-> {what or self._describe(data)}")
        self._transport.sendto(data, self.robot)

    def _describe(self, data: bytes) -> str:
        """A datagram this probe sends, for the transcript (it may be malformed on purpose)."""
        try:
            header = pull_header(data)
        except ProtocolError as error:
            return f"{len(data)} bytes {data[:24].hex()} ({error.reason})"
        body: Body | None = None
        try:
            if header.encryption is Encryption.NONE or header.type in UNSEALED:
                body = self.codec.pull_body(header, data[HEADER_SIZE:])
        except ProtocolError as error:
            return f"{header.type.name} #{header.sequence} malformed: {error.reason}"
        if isinstance(body, MapBody):  # the devices the case drives or asks for
            devices = self.model.devices
            self.transcript.uses(*(devices[item.device].name for item in body.items))
        return summary(self.model, header, body)

    # -- receiving -----------------------------------------------------------------------------

    def _error(self, error: Exception) -> None:
        self.transcript.note(f"UDP error: {error}")

    def _arrived(self, data: bytes, source: Address, at: float) -> None:
        self.transcript.packet("udp", source, self.local, data)
        if source != self.robot:
            self.transcript.note(f"{self._who}<- {len(data)} bytes from {source}: ignored")
            return
        found = self._decode(data, at)
        if found is not None:
            self.keep(found)
            self.transcript.note(f"{self._who}<- {summary(self.model, found.header, found.body)}")
            self._learn(found)
        self._arrival.set()
        if self.endpoint is not None:
            if self._backward is not None:
                self._backward.send(data, self.now)
            else:
                self.endpoint.receive_datagram(data, self.now)
            self._pump()

    def _decode(self, data: bytes, at: float) -> Datagram | None:
        """The datagram read by the codec; a fault of the robot's (kept for `check`) if not."""
        try:
            header = pull_header(data)
            if header.model_id != self.model.model_id and header.type is not PacketType.REFUSED:
                raise ProtocolError(
                    f"model ID {header.model_id}, not {self.model.model_id}", MODEL_AT, "R-RSP-13"
                )
        except ProtocolError as error:
            odd = self._odd_refused(data, at)
            if odd is not None:
                return odd
            self._fail(error.rule or "R-RSP-13", "the 20-byte header of D-RSP-10", data, error)
            return None
        body: Body | None = None
        plain = data[HEADER_SIZE:]
        if header.encryption is not Encryption.NONE and header.type not in UNSEALED:
            opener = self._openers.get(header.session_id)
            if opener is None:
                return Datagram(at, data, header, None)
            try:
                plain = opener.open(data, header.sequence)
            except ProtocolError as error:
                self._fail(SEALING, "a body sealed with the session's keys", data, error)
                return None
        try:
            body = self.codec.pull_body(header, plain)
        except ProtocolError as error:
            self._fail(error.rule or LAYOUT, f"a {header.type.name} body of D-RSP-11", data, error)
            return None
        return Datagram(at, data, header, body)

    def _odd_refused(self, data: bytes, at: float) -> Datagram | None:
        """A REFUSED echoing an encryption byte no AEAD has, as D-RSP-12 asks (it echoes the
        HELLO's, whatever it is): read, not counted against the header's layout."""
        if len(data) != HEADER_SIZE + 1 or data[VERSION_AT] != 1:
            return None
        version, model_id, encryption, kind, sequence, stamp, high, low, last, buffer = (
            HEADER_LAYOUT.unpack(data[:HEADER_SIZE])
        )
        if kind != PacketType.REFUSED or encryption in tuple(Encryption) or high or low:
            return None
        try:
            reason = RefusedReason(data[HEADER_SIZE])
        except ValueError:
            return None
        header = Header(
            version,
            model_id,
            cast(Encryption, encryption),
            PacketType.REFUSED,
            sequence,
            stamp,
            0,
            last,
            buffer,
        )
        return Datagram(at, data, header, Refused(reason))

    def _learn(self, found: Datagram) -> None:
        """A WELCOME to one of our HELLOs gives the keys to read the session's packets."""
        body = found.body
        if not isinstance(body, Welcome) or body.client_nonce not in self._nonces:
            return
        encryption = found.header.encryption
        if encryption is not Encryption.NONE and self.psk is not None:
            key = session_key(
                self.psk, body.client_nonce, body.robot_nonce, found.header.session_id,
                Direction.UPLINK,
            )  # fmt: skip
            opener = _Opener(Sealer(encryption, key))
            opener.tracker.see(found.header.sequence)
            self._openers.setdefault(found.header.session_id, opener)
        for raw in self.raw_sessions:
            raw.welcomed(found)

    # -- the endpoint --------------------------------------------------------------------------

    async def open_session(
        self,
        *,
        encryption: Encryption = Encryption.NONE,
        period: float | None = None,
        nonce: bytes | None = None,
    ) -> events.SessionOpened:
        """A session run by the core's `LocalEndpoint`: HELLO, and WELCOME within the wait.
        Inconclusive when the robot refuses or does not answer (the rsp/session cases check the
        handshake itself)."""
        if self.endpoint is not None:
            raise RuntimeError("the probe runs one endpoint")
        if encryption is not Encryption.NONE and self.psk is None:
            raise NotApplicable("the robot's pre-shared key is not known (ICS [rsp] psk-file)")
        nonce = os.urandom(NONCE_SIZE) if nonce is None else nonce
        self._nonces.add(nonce)
        self.endpoint = LocalEndpoint(
            self.model, period=period, encryption=encryption, psk=self.psk, nonce=nonce
        )
        self.endpoint.connect(self.now)
        self._pump()
        found = await self.event(
            lambda e: isinstance(
                e, events.SessionOpened | events.SessionRefused | events.SessionClosed
            )
        )
        if isinstance(found, events.SessionOpened):
            return found
        if isinstance(found, events.SessionRefused) and found.reason is not None:
            raise Inconclusive(f"the robot refused the session: {found.reason.name}")
        if found is None:
            raise Inconclusive(f"no session with the robot within {self.wait:.2g} s")
        assert isinstance(found, events.SessionRefused | events.SessionClosed)
        raise Inconclusive(f"no session with the robot: {session_end(found)}")

    @property
    def session(self) -> LocalEndpoint:
        if self.endpoint is None:
            raise RuntimeError("no endpoint: open_session() first")
        return self.endpoint

    def poke(self) -> None:
        """Send what the endpoint has now (after a call of the case's) and move its timer."""
        self._pump()

    def mutate_next(self, mutation: Callable[[bytes], bytes | None]) -> None:
        """Apply `mutation` to the endpoint's next datagram (None: do not send it)."""
        self._mutations.append(mutation)

    async def event(
        self, where: Callable[[events.Event], bool], *, wait: float | None = None, after: int = 0
    ) -> events.Event | None:
        """The first endpoint event from index `after` for which `where` holds, within `wait`."""
        deadline = self.now + (self.wait if wait is None else wait)
        start = after
        while True:
            self.check()
            for _, event in self.events[start:]:
                if where(event):
                    return event
            start = len(self.events)
            remaining = deadline - self.now
            if remaining <= 0:
                return None
            self._event.clear()
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(self._event.wait(), remaining)

    async def state(
        self,
        device: str,
        where: Callable[[Mapping[str, Value]], bool] = lambda _: True,
        *,
        wait: float | None = None,
        since: float | None = None,
    ) -> Mapping[str, Value] | None:
        """The first value of a sensor or monitor received from `since` (loop time; by default
        now) for which `where` holds, within `wait`; None if none."""
        start = self.now if since is None else since

        def fits(event: events.Event) -> bool:
            return (
                isinstance(event, events.StateReceived)
                and event.device == device
                and where(event.values)
            )

        seen = self.events
        first = next((i for i, (at, _) in seen.places() if at >= start), len(seen))
        found = await self.event(fits, wait=wait, after=first)
        return found.values if isinstance(found, events.StateReceived) else None

    def _pump(self) -> None:
        """Everything due now: impaired datagrams delivered, the endpoint's timer and output."""
        if self.closed:
            return
        now = self.now
        if self._backward is not None and self.endpoint is not None:
            for data in self._backward.due(now):
                self.endpoint.receive_datagram(data, now)
        endpoint = self.endpoint
        if endpoint is not None:
            timer = endpoint.get_timer()
            if timer is not None and timer <= now:
                endpoint.handle_timer(now)
            for data in endpoint.datagrams_to_send(now):
                self._endpoint_out(data)
            while (event := endpoint.next_event()) is not None:
                self.events.append((now, event))
                if isinstance(event, events.StateReceived):
                    self.states[event.device] = (now, event.values)
                elif not isinstance(event, events.OccurrenceReceived | events.Acknowledged):
                    self.transcript.note(f"{self._who}   endpoint: {event}")
                self._event.set()
        self._arm()

    def _endpoint_out(self, data: bytes) -> None:
        if self._mutations:
            changed = self._mutations.pop(0)(data)
            if changed is None:
                self.transcript.note(f"{self._who}-x {self._describe(data)} (withheld)")
                return
            data = changed
        if self.muted:
            return
        self.send(data)

    def _arm(self) -> None:
        times = [
            t
            for t in (
                self.endpoint.get_timer() if self.endpoint is not None else None,
                self._backward.get_timer() if self._backward is not None else None,
            )
            if t is not None
        ]
        at = min(times, default=None)
        if at == self._timer_at and self._timer is not None:
            return
        if self._timer is not None:
            self._timer.cancel()
            self._timer = None
        self._timer_at = at
        if at is not None:
            self._timer = self._loop.call_at(max(at, self.now), self._fired)

    def _fired(self) -> None:
        self._timer = None
        self._timer_at = None
        self._pump()

    # -- sessions by hand ----------------------------------------------------------------------

    def adopt(self, session: HandDriven) -> None:
        """A session the case drives by hand on this probe's socket: its WELCOME is handed to it,
        and its BYE ends it with the case."""
        self.raw_sessions.append(session)
        self._nonces.add(session.nonce)

    # -- the end -------------------------------------------------------------------------------

    def close(self) -> None:
        """BYE to whatever session the robot holds for this probe, and the socket closed. What the
        impairment still holds goes first (a BYE of the case's among it), then the BYE, straight
        to the socket: an impairment must not keep the robot busy."""
        if self.closed:
            return
        self.noted_left_out()
        if self._forward is not None:
            self._forward.close(flush=True)
            self._forward = None
        now = self.now
        if self.endpoint is not None and self.endpoint.state == "open":
            self.endpoint.close(now)
            for data in self.endpoint.datagrams_to_send(now):
                self._put(data, "BYE (the case ends)")
        for raw in self.raw_sessions:
            with contextlib.suppress(EncodeError):
                bye = raw.closing_bye()
                if bye is not None:
                    self._put(bye, "BYE (the case ends)")
        self.closed = True
        if self._timer is not None:
            self._timer.cancel()
        if self._transport is not None:
            self._transport.close()


async def open_probe(ctx: Context, *, robot: Address | None = None, name: str = "") -> RspProbe:
    """A probe on one of the target's RSP robots (taken for the case alone), or on `robot`
    (another local system of the same robot, `name` marking its lines in the transcript);
    closed with the case. NotApplicable without an RSP robot or its model."""
    model = ctx.target.rsp_model
    if model is None:
        raise NotApplicable("the RSP robot's model is not known (give --rsp-model)")
    address = await ctx.rsp() if robot is None else robot
    probe = RspProbe(
        model,
        address,
        ctx.transcript,
        ctx.wait,
        ctx.target.rsp_psk,
        ctx.impairment,  # --impair's, else the case's
        ctx.impairment_seed(name),
        name,
    )
    probe.quiet = QUIET * ctx.scale
    ctx.watch(*probe.channels)
    await probe._bind()
    ctx.on_close(probe.close)
    return probe
