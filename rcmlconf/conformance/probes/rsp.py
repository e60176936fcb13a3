"""An RSP local system as a case drives it, over real UDP on 127.0.0.1 (specs/rsp.md).

A probe is one UDP socket talking to one robot. It can run the core's sans-IO `LocalEndpoint`
(`open_session`: the session a well-behaved local system keeps, with its DOWNLINK every T, its
retransmissions and ACKs), and it can send datagrams the case builds by hand (`RawSession`, whose
packets are numbered, stamped and sealed by the core's `SessionWire` and may then be altered byte
by byte, or `send` of any bytes at all). Both at once: every datagram the robot sends is decoded
with the core's codec and kept in `received`, whoever asked for it.

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
import struct
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from typing import cast

from rcmlconf.conformance.context import Context
from rcmlconf.conformance.probes.datagrams import DatagramLog
from rcmlconf.conformance.probes.impaired import ImpairedPath
from rcmlconf.conformance.transcript import Address, Transcript
from rcmlconf.conformance.verdicts import Failed, HarnessError, Inconclusive, NotApplicable
from rcmlconf.errors import EncodeError, ProtocolError
from rcmlconf.impair import ImpairedChannel, Impairment, derive_seed
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
)
from rcmlconf.rsp.codec.bodies import Body, Period
from rcmlconf.rsp.layout import HEADER_SIZE, MAC_SIZE, NONCE_SIZE
from rcmlconf.rsp.model import Device, DeviceKind, Field, RobotModel
from rcmlconf.rsp.security import Direction, Sealer, mac, session_key
from rcmlconf.rsp.session import events
from rcmlconf.rsp.session.local import LocalEndpoint
from rcmlconf.rsp.session.wire import SessionWire
from rcmlconf.values import Kind, Value

#: The requirement a robot datagram the codec refuses breaks, when its error names none.
LAYOUT = "R-RSP-16"
#: A sealed body that does not open with the session's keys (D-RSP-21).
SEALING = "R-RSP-37"
#: How long a case listens for something that must not come (an answer to a dropped packet):
#: a robot acknowledges at once (D-RSP-17), so a dozen periods is ample.
QUIET = 0.25
#: Header field offsets (D-RSP-10).
VERSION_AT, MODEL_AT, ENCRYPTION_AT, TYPE_AT, SEQUENCE_AT = 0, 1, 3, 4, 5
TIMESTAMP_AT, SESSION_AT, LAST_AT, BUFFER_AT = 7, 11, 17, 19
_SEQUENCE = 1 << 16
_HEADER = struct.Struct(">BHBBHIHIHB")
_UNSEALED = frozenset({PacketType.HELLO, PacketType.WELCOME, PacketType.REFUSED})


@dataclass(frozen=True, slots=True)
class Datagram:
    """One datagram from the robot, as the socket received it and the codec read it."""

    #: Loop time of its arrival.
    at: float
    data: bytes
    header: Header
    #: None when it is sealed with keys the probe does not have.
    body: Body | None

    @property
    def type(self) -> PacketType:
        return self.header.type

    @property
    def items(self) -> tuple[Item, ...]:
        """A map packet's items (empty for any other)."""
        return self.body.items if isinstance(self.body, MapBody) else ()

    def devices(self, model: RobotModel) -> set[str]:
        return {model.devices[item.device].name for item in self.items}

    def item(self, position: int) -> Item | None:
        return next((item for item in self.items if item.device == position), None)

    def acks(self, position: int) -> list[int]:
        """The IDs an ACK acknowledges for the device at `position`."""
        if self.type is not PacketType.ACK:
            return []
        return [item.id for item in self.items if item.device == position and item.id is not None]


Where = Callable[[Datagram], bool]


def newer(sequence: int, than: int) -> bool:
    """`sequence` is `than` or ahead of it by up to 32,767 (serial arithmetic, D-RSP-15)."""
    return (sequence - than) % _SEQUENCE < _SEQUENCE // 2


# -- building packets ---------------------------------------------------------------------------


def patch(data: bytes, offset: int, new: bytes) -> bytes:
    """`data` with `new` written over it at `offset`."""
    return data[:offset] + new + data[offset + len(new) :]


def sequence_of(data: bytes) -> int:
    """The sequence number of a packet we built (D-RSP-10)."""
    return int.from_bytes(data[SEQUENCE_AT : SEQUENCE_AT + 2])


def flip(data: bytes, offset: int, mask: int = 0x01) -> bytes:
    return patch(data, offset, bytes([data[offset] ^ mask]))


def hello_packet(
    model_id: int,
    encryption: int,
    nonce: bytes,
    period_ms: int,
    *,
    sequence: int = 0,
    psk: bytes | None = None,
    signed: bool | None = None,
) -> bytes:
    """A HELLO of any model and encryption byte (D-RSP-11), its MAC made with `psk` (D-RSP-21);
    `signed` says whether it carries a MAC (by default: when the encryption is not NONE)."""
    header = _HEADER.pack(1, model_id, encryption, PacketType.HELLO, sequence, 0, 0, 0, 0, 0)
    unsigned = header + nonce + struct.pack(">H", period_ms)
    if signed is None:
        signed = encryption != Encryption.NONE
    if not signed:
        return unsigned
    return unsigned + (mac(psk, unsigned) if psk is not None else bytes(MAC_SIZE))


# -- reading the robot's datagrams --------------------------------------------------------------


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


def summary(model: RobotModel, header: Header, body: Body | None) -> str:
    """One line of a packet, for the transcript."""
    kind = header.type
    name = kind.name if isinstance(kind, PacketType) else f"type {kind}"
    head = f"{name} #{header.sequence}"
    if kind is PacketType.HELLO and isinstance(body, Hello):
        return (
            f"{head} model={header.model_id} enc={int(header.encryption)}"
            f" nonce={body.client_nonce[:4].hex()}.. period={body.period_ms}ms"
            + (f" mac={body.mac[:4].hex()}.." if body.mac else "")
        )
    if kind is PacketType.REFUSED and isinstance(body, Refused):
        return (
            f"{head} model={header.model_id} enc={int(header.encryption)} {body.reason.name}"
            f" last={header.last_received}"
        )
    text = (
        f"{head} t={header.timestamp} sid={header.session_id:x} last={header.last_received}"
        f" buf={header.buffer:#x}"
    )
    if header.model_id != model.model_id or header.encryption:
        text += f" model={header.model_id} enc={int(header.encryption)}"
    if body is None:
        return text + " (sealed)"
    if isinstance(body, Welcome):
        return text + f" nonce={body.robot_nonce[:4].hex()}.. period={body.period_ms}ms"
    if isinstance(body, Bye | Refused):
        return text + f" {body.reason.name}"
    if isinstance(body, Period):
        return text + f" period={body.period_ms}ms"
    if isinstance(body, MapBody):
        return text + " [" + ", ".join(_item(model, item) for item in body.items) + "]"
    return text


def _item(model: RobotModel, item: Item) -> str:
    text = model.devices[item.device].name
    if item.id is not None:
        text += f"#{item.id}"
    if item.values is not None:
        shown = ",".join(f"{k}={_value(v)}" for k, v in item.values.items())
        text += "{" + shown + "}"
    return text


def _value(value: Value) -> str:
    if isinstance(value, bytes):
        return f"<{len(value)} bytes>"
    if isinstance(value, float):
        return f"{value:.3g}"
    if isinstance(value, tuple):
        return "(" + ",".join(_value(v) for v in value) + ")"
    return str(value)


# -- the probe ----------------------------------------------------------------------------------


class _Socket(asyncio.DatagramProtocol):
    def __init__(self, probe: RspProbe) -> None:
        self.probe = probe

    def datagram_received(self, data: bytes, addr: tuple[str | int, ...]) -> None:
        self.probe._arrived(data, (str(addr[0]), int(addr[1])))

    def error_received(self, exc: Exception) -> None:
        self.probe.transcript.note(f"UDP error: {exc}")


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
        #: Every datagram from the robot, in arrival order.
        self.received: list[Datagram] = []
        #: Every datagram this probe put on the wire: (loop time, bytes).
        self.sent: list[tuple[float, bytes]] = []
        self._arrival = asyncio.Event()
        self.fault: Failed | None = None
        #: Client nonces of this probe's HELLOs: WELCOMEs to them give the keys to read with.
        self._nonces: set[bytes] = set()
        self._openers: dict[int, _Opener] = {}
        #: Sessions the robot opened for this probe (WELCOME seen), not yet ended, for close().
        self.raw_sessions: list[RawSession] = []
        # The endpoint, its events and the newest state of each device.
        self.endpoint: LocalEndpoint | None = None
        self.events: list[tuple[float, events.Event]] = []
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
                lambda: _Socket(self), local_addr=("127.0.0.1", 0)
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

    def _leave(self, data: bytes, _: Address, lost: int) -> None:
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
            if header.encryption is Encryption.NONE or header.type in _UNSEALED:
                body = self.codec.pull_body(header, data[HEADER_SIZE:])
        except ProtocolError as error:
            return f"{header.type.name} #{header.sequence} malformed: {error.reason}"
        if isinstance(body, MapBody):  # the devices the case drives or asks for
            devices = self.model.devices
            self.transcript.uses(*(devices[item.device].name for item in body.items))
        return summary(self.model, header, body)

    # -- receiving -----------------------------------------------------------------------------

    def _arrived(self, data: bytes, source: Address) -> None:
        self.transcript.packet("udp", source, self.local, data)
        if source != self.robot:
            self.transcript.note(f"{self._who}<- {len(data)} bytes from {source}: ignored")
            return
        found = self._decode(data)
        if found is not None:
            self.received.append(found)
            self.transcript.note(f"{self._who}<- {summary(self.model, found.header, found.body)}")
            self._learn(found)
        self._arrival.set()
        if self.endpoint is not None:
            if self._backward is not None:
                self._backward.send(data, self.now)
            else:
                self.endpoint.receive_datagram(data, self.now)
            self._pump()

    def _decode(self, data: bytes) -> Datagram | None:
        """The datagram read by the codec; a fault of the robot's (kept for `check`) if not."""
        try:
            header = pull_header(data)
            if header.model_id != self.model.model_id and header.type is not PacketType.REFUSED:
                raise ProtocolError(
                    f"model ID {header.model_id}, not {self.model.model_id}", MODEL_AT, "R-RSP-13"
                )
        except ProtocolError as error:
            odd = self._odd_refused(data)
            if odd is not None:
                return odd
            self._fail(error.rule or "R-RSP-13", "the 20-byte header of D-RSP-10", data, error)
            return None
        body: Body | None = None
        plain = data[HEADER_SIZE:]
        if header.encryption is not Encryption.NONE and header.type not in _UNSEALED:
            opener = self._openers.get(header.session_id)
            if opener is None:
                return Datagram(self.now, data, header, None)
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
        return Datagram(self.now, data, header, body)

    def _odd_refused(self, data: bytes) -> Datagram | None:
        """A REFUSED echoing an encryption byte no AEAD has, as D-RSP-12 asks (it echoes the
        HELLO's, whatever it is): read, not counted against the header's layout."""
        if len(data) != HEADER_SIZE + 1 or data[VERSION_AT] != 1:
            return None
        version, model_id, encryption, kind, sequence, stamp, high, low, last, buffer = (
            _HEADER.unpack(data[:HEADER_SIZE])
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
        return Datagram(self.now, data, header, Refused(reason))

    def _fail(self, rule: str, expected: str, data: bytes, error: ProtocolError) -> None:
        actual = f"{error.reason} at byte {error.offset} of {data[:32].hex()}"
        self.transcript.note(f"{self._who}<- {len(data)} bytes the codec refuses: {actual}")
        if self.fault is None:
            self.fault = Failed(rule, expected, actual)

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
            if raw.nonce == body.client_nonce and raw.wire.session_id == 0:
                raw.accept(found)

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
        raise Inconclusive(f"no session with the robot within {self.wait:.2g} s ({found})")

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
            for index in range(start, len(self.events)):
                if where(self.events[index][1]):
                    return self.events[index][1]
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

        first = next((i for i, (at, _) in enumerate(self.events) if at >= start), len(self.events))
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

    def raw(
        self,
        encryption: Encryption = Encryption.NONE,
        *,
        period_ms: int | None = None,
        nonce: bytes | None = None,
        psk: bytes | None = None,
    ) -> RawSession:
        """A session the case drives packet by packet (`RawSession`)."""
        if encryption is not Encryption.NONE and (psk or self.psk) is None:
            raise NotApplicable("the robot's pre-shared key is not known (ICS [rsp] psk-file)")
        raw = RawSession(self, encryption, period_ms, nonce, psk or self.psk)
        self.raw_sessions.append(raw)
        self._nonces.add(raw.nonce)
        return raw

    # -- the end -------------------------------------------------------------------------------

    def close(self) -> None:
        """BYE to whatever session the robot holds for this probe, and the socket closed. What the
        impairment still holds goes first (a BYE of the case's among it), then the BYE, straight
        to the socket: an impairment must not keep the robot busy."""
        if self.closed:
            return
        if self._forward is not None:
            self._forward.close(flush=True)
            self._forward = None
        now = self.now
        if self.endpoint is not None and self.endpoint.state == "open":
            self.endpoint.close(now)
            for data in self.endpoint.datagrams_to_send(now):
                self._put(data, "BYE (the case ends)")
        for raw in self.raw_sessions:
            if raw.wire.session_id and not raw.ended:
                with contextlib.suppress(EncodeError):
                    self._put(raw.last_bye(), "BYE (the case ends)")
        self.closed = True
        if self._timer is not None:
            self._timer.cancel()
        if self._transport is not None:
            self._transport.close()


class RawSession:
    """A session packet by packet: the core's `SessionWire` numbers, stamps and seals what the
    case builds; the case may alter the bytes before they go (`send(..., mutate=...)`)."""

    def __init__(
        self,
        probe: RspProbe,
        encryption: Encryption,
        period_ms: int | None,
        nonce: bytes | None,
        psk: bytes | None,
    ) -> None:
        self.probe = probe
        self.wire = SessionWire(probe.codec, encryption, Direction.DOWNLINK)
        self.encryption = encryption
        self.period_ms = round(probe.model.period * 1000) if period_ms is None else period_ms
        self.nonce = os.urandom(NONCE_SIZE) if nonce is None else nonce
        self.psk = psk
        self.welcome: Datagram | None = None
        self.ended = False
        #: Items every `downlink` carries besides its own (the requests a local system repeats in
        #: every DOWNLINK, R-RSP-23): a device the call names itself is not added twice.
        self.standing: list[Item] = []
        #: The last packet `send` sent (as it went, altered or not).
        self.last = b""

    @property
    def session_id(self) -> int:
        return self.wire.session_id

    @property
    def period(self) -> float:
        """T in force, seconds: WELCOME's, else HELLO's."""
        if self.welcome is not None and isinstance(self.welcome.body, Welcome):
            return self.welcome.body.period_ms / 1000
        return self.period_ms / 1000

    @property
    def next_sequence(self) -> int:
        return self.wire.sent % _SEQUENCE

    def hello(self, *, psk: bytes | None = None) -> bytes:
        """Send HELLO (the next sequence number, this session's nonce); `psk` signs it instead
        of the robot's key (a wrong one, for the cases that want it refused)."""
        signed = self.encryption is not Encryption.NONE
        body = Hello(self.nonce, self.period_ms, bytes(MAC_SIZE) if signed else b"")
        data = self.wire.build(PacketType.HELLO, body, self.probe.now, 0, psk or self.psk)
        self.probe.send(data)
        self.last = data
        return data

    async def open(self) -> Datagram:
        """HELLO and the robot's WELCOME; Inconclusive when it refuses or does not answer."""
        answer = await self.probe.answer_to(
            self.hello,
            (PacketType.WELCOME, PacketType.REFUSED),
            where=lambda d: (
                d.type is PacketType.REFUSED
                or (isinstance(d.body, Welcome) and d.body.client_nonce == self.nonce)
            ),
        )
        if answer is None:
            raise Inconclusive(f"no answer to HELLO within {self.probe.wait:.2g} s")
        if isinstance(answer.body, Refused):
            raise Inconclusive(f"the robot refused the session: {answer.body.reason.name}")
        if self.welcome is None:
            self.accept(answer)
        return answer

    async def expect_welcome(self, requirement: str, expected: str = "WELCOME") -> Datagram:
        """HELLO and the robot's answer, as `open`, for a case that checks the handshake itself:
        Failed (`requirement`, `expected`) when it refuses or does not answer, and any WELCOME
        taken (its nonce is the case's to check)."""
        answer = await self.probe.expect_answer_to(
            self.hello,
            (PacketType.WELCOME, PacketType.REFUSED),
            requirement,
            expected=expected,
        )
        if isinstance(answer.body, Refused):
            raise Failed(requirement, expected, f"REFUSED {answer.body.reason.name}")
        if self.welcome is None:
            self.accept(answer)
        return answer

    def accept(self, welcome: Datagram) -> None:
        """The robot's WELCOME: the session's ID, and its keys (D-RSP-21)."""
        body = welcome.body
        assert isinstance(body, Welcome)
        self.welcome = welcome
        self.wire.session_id = welcome.header.session_id
        self.wire.tracker.see(welcome.header.sequence)
        self.wire.secure(self.psk or b"", self.nonce, body.robot_nonce)

    def build(self, kind: PacketType, body: Body, *, buffer: int = 0) -> bytes:
        """The next packet of the session (numbered, stamped, sealed)."""
        if kind is PacketType.BYE:
            self.ended = True
        return self.wire.build(kind, body, self.probe.now, buffer, self.psk)

    def send(
        self,
        kind: PacketType,
        body: Body,
        *,
        buffer: int = 0,
        mutate: Callable[[bytes], bytes] | None = None,
        what: str = "",
    ) -> bytes:
        """Build the next packet, alter it with `mutate`, send it; the bytes sent."""
        data = self.build(kind, body, buffer=buffer)
        if mutate is not None:
            data = mutate(data)
        self.probe.send(data, what)
        self.last = data
        return data

    def downlink(
        self,
        items: Iterable[Item] = (),
        *,
        buffer: int = 0,
        mutate: Callable[[bytes], bytes] | None = None,
        what: str = "",
    ) -> bytes:
        """A DOWNLINK of `items` and the standing ones (in any order: sorted into model order)."""
        given = {item.device: item for item in self.standing}
        given.update((item.device, item) for item in items)
        body = MapBody(tuple(given[device] for device in sorted(given)))
        return self.send(PacketType.DOWNLINK, body, buffer=buffer, mutate=mutate, what=what)

    def bye(self, reason: ByeReason = ByeReason.CLOSED) -> bytes:
        """BYE, sent again while the impairment spoils it (the robot answers none, and a case
        ending the session means it: the next one must not be refused as busy); the last sent."""
        self.probe.send_intact(lambda: self.send(PacketType.BYE, Bye(reason)))
        return self.last

    def last_bye(self) -> bytes:
        """The BYE that ends the case, numbered after the newest sequence number the robot can
        have taken: the last it reported (R-RSP-15), or one of ours newer than that. A case that
        skipped or rewound numbers, or lost some to the impairment, may have left the robot
        behind our own count, where a BYE would be dropped as stale (D-RSP-15) and the robot
        kept busy."""
        mine = [d for d in self.probe.received if d.header.session_id == self.session_id]
        newest = mine[-1].header.last_received if mine else 0
        for _, data in self.probe.sent:
            if int.from_bytes(data[SESSION_AT : SESSION_AT + 6]) == self.session_id:
                sequence = sequence_of(data)
                if newer(sequence, newest):
                    newest = sequence
        self.wire.sent = newest + 1
        return self.build(PacketType.BYE, Bye(ByeReason.CLOSED))

    def skip(self, packets: int) -> None:
        """Number the next packet `packets` further on, as if that many had been lost."""
        self.wire.sent += packets

    def rewind(self, sequence: int) -> None:
        """Number the next packet `sequence` (a late or repeated number, on purpose)."""
        self.wire.sent = sequence


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


# -- the model, as cases pick devices from it ---------------------------------------------------


def of_kind(model: RobotModel, *kinds: DeviceKind) -> list[Device]:
    return [d for d in model.devices if d.kind in kinds]


def numeric(device: Device) -> bool:
    return bool(device.fields) and all(f.type.base.numeric for f in device.fields)


def zero_values(device: Device) -> dict[str, Value]:
    """Every field at D-RSP-20's safe value: a valid payload of any device with fields."""
    return {f.name: f.zero() for f in device.fields}


def visible(field: Field) -> Value:
    """A value of a numeric field well away from 0 and within its range."""
    kind = field.type.base.kind
    high = field.maximum if field.maximum is not None else 1000
    low = field.minimum if field.minimum is not None else -1000
    target = high * 0.4 if high > 0 else low * 0.4
    if low > 0:
        target = low + (high - low) * 0.4
    item: int | float = float(target) if kind is Kind.FLOAT else round(target)
    return tuple([item] * field.type.count) if field.type.is_array else item


def modules_of(model: RobotModel, *found: Device) -> list[Device]:
    """The modules holding `found`, to activate."""
    names = {d.module for d in found if d.module is not None}
    return [d for d in model.devices if d.kind is DeviceKind.MODULE and d.name in names]


def monitored(
    model: RobotModel, where: Callable[[Device], bool] = lambda _: True
) -> tuple[Device, Device]:
    """An effector with all-numeric fields and a monitor of it (`where` holds of the effector);
    NotApplicable when the model has none."""
    for monitor in of_kind(model, DeviceKind.MONITOR):
        effector = model.device(monitor.of or "")
        if effector is not None and numeric(effector) and where(effector):
            return effector, monitor
    raise NotApplicable(f"{model.name} has no numeric effector with a monitor that fits")


def first(model: RobotModel, kind: DeviceKind) -> Device:
    for found in model.devices:
        if found.kind is kind:
            return found
    raise NotApplicable(f"{model.name} has no {kind.value}")


def flags(model: RobotModel, *found: Device) -> list[Item]:
    """DOWNLINK items requesting `found` (sensors, monitors, events) with their modules active
    (an effector among them brings its module only: its value is the case's to give)."""
    wanted = {d.position for d in found if d.kind is not DeviceKind.EFFECTOR}
    wanted |= {m.position for m in modules_of(model, *found)}
    return [Item(position) for position in sorted(wanted)]


def occurrence(found: Device, ident: int, values: Mapping[str, Value] | None = None) -> Item:
    """A command or memory command of ID `ident` (its fields at their safe values by default)."""
    return Item(found.position, ident, dict(values) if values is not None else zero_values(found))


def value_item(found: Device, values: Mapping[str, Value]) -> Item:
    return Item(found.position, None, dict(values))


def close_to(field: Field, actual: Value | None, wanted: Value) -> bool:
    """A numeric value as an effector's monitor reads it: within 1 % of the range (or 1)."""
    if not isinstance(actual, int | float) or not isinstance(wanted, int | float):
        return actual == wanted
    span = (
        field.maximum - field.minimum
        if field.maximum is not None and field.minimum is not None
        else 100
    )
    return abs(actual - wanted) <= max(1.0, span / 100)


async def raw_session(
    ctx: Context, encryption: Encryption = Encryption.NONE
) -> tuple[RspProbe, RawSession]:
    """A probe with a session opened by hand (HELLO, WELCOME)."""
    probe = await open_probe(ctx)
    raw = probe.raw(encryption)
    await raw.open()
    return probe, raw


async def reporting(
    ctx: Context, *, slower: int = 1
) -> tuple[RspProbe, events.SessionOpened, Device]:
    """A session of the core's endpoint, T `slower` times the model's, requesting the sensor or
    monitor with the smallest payload (`reported`), which the robot then reports every T."""
    probe = await open_probe(ctx)
    opened = await probe.open_session(period=slower * probe.model.period)
    sensor = reported(probe.model, 1)[0]
    probe.session.set_active(sensor.name, True)
    return probe, opened, sensor


async def acked(
    probe: RspProbe,
    raw: RawSession,
    found: Device,
    ident: int,
    values: Mapping[str, Value] | None = None,
    *,
    buffer: int = 0,
) -> Datagram | None:
    """Send occurrence `ident` of command or memory command `found` in a DOWNLINK (again while
    the impairment spoils it) and return the robot's ACK of it (R-RSP-26); None if none came."""
    return await probe.answer_to(
        lambda: raw.downlink([occurrence(found, ident, values)], buffer=buffer),
        PacketType.ACK,
        where=lambda d: ident in d.acks(found.position),
    )


async def taken(
    probe: RspProbe,
    raw: RawSession,
    items: Iterable[Item] = (),
    *,
    buffer: int = 0,
    where: Where | None = None,
    wait: float | None = None,
) -> Datagram | None:
    """Send a DOWNLINK of `items` (again, a new packet, while the impairment spoils it) and return
    the first UPLINK the robot sent after it took it (its last received sequence number has
    reached it, R-RSP-15) for which `where` holds; None if none came within `wait`."""

    def fits(d: Datagram) -> bool:
        return newer(d.header.last_received, sequence_of(raw.last)) and (where is None or where(d))

    return await probe.answer_to(
        lambda: raw.downlink(items, buffer=buffer), PacketType.UPLINK, where=fits, wait=wait
    )


async def ack_of(
    probe: RspProbe, found: Device, ident: int, *, after: int, wait: float | None = None
) -> Datagram | None:
    """The robot's ACK of occurrence `ident` of `found` received from `after`, within `wait`."""
    return await probe.next(
        PacketType.ACK, after=after, wait=wait, where=lambda d: ident in d.acks(found.position)
    )


async def fresh_uplink(
    probe: RspProbe, sequence: int, *, wait: float | None = None, where: Where | None = None
) -> Datagram | None:
    """The first UPLINK the robot sent after it received our packet `sequence` (its last
    received sequence number has reached it, R-RSP-15)."""

    def fits(d: Datagram) -> bool:
        return newer(d.header.last_received, sequence) and (where is None or where(d))

    return await probe.next(PacketType.UPLINK, after=0, wait=wait, where=fits)


def reported(model: RobotModel, count: int = 2) -> list[Device]:
    """`count` sensors or monitors with the smallest payloads, those outside modules first (a
    case requesting them has the fewest bytes and bits to handle); NotApplicable if fewer."""
    found = of_kind(model, DeviceKind.SENSOR, DeviceKind.MONITOR)
    found.sort(key=lambda d: (d.module is not None, sum(f.type.max_encoded_size for f in d.fields)))
    if len(found) < count:
        raise NotApplicable(f"{model.name} has fewer than {count} sensors and monitors")
    return found[:count]


def values_of(found: Datagram, device: Device) -> Mapping[str, Value] | None:
    """The values an UPLINK reports of a sensor or monitor; None if it does not."""
    item = found.item(device.position)
    return item.values if item is not None else None


async def dropped_then_taken(
    ctx: Context,
    probe: RspProbe,
    raw: RawSession,
    mutate: Callable[[bytes], bytes],
    requirement: str,
    what: str,
    *,
    sender: RspProbe | None = None,
) -> None:
    """A command in a DOWNLINK altered by `mutate` (sent from `sender`, by default the probe)
    must be dropped without an answer (no ACK within the quiet time); then the same command in a
    well-formed DOWNLINK must be acknowledged: the bad packet did not end the session."""
    command = first(probe.model, DeviceKind.COMMAND)
    ident = 7
    start = probe.mark()
    bad = mutate(raw.build(PacketType.DOWNLINK, MapBody((occurrence(command, ident),))))
    (sender or probe).send(bad, f"{what}: {probe._describe(bad)}")
    await probe.listen(probe.quiet)
    answers = [d for d in probe.packets(after=start) if d.type is not PacketType.UPLINK]
    ctx.expect(
        not answers,
        f"{what} dropped without an answer (no ACK)",
        ", ".join(summary(probe.model, d.header, d.body) for d in answers),
        requirement,
    )
    if sender is not None:
        stray = sender.packets()
        ctx.expect(
            not stray,
            "no answer to the other address",
            f"{len(stray)} datagrams",
            requirement,
        )
    ack = await acked(probe, raw, command, ident)
    ctx.expect(
        ack is not None,
        f"the session going on: ACK of {command.name} #{ident} in a well-formed DOWNLINK",
        "no ACK",
        requirement,
    )


async def replay_dropped(ctx: Context, probe: RspProbe, raw: RawSession, ident: int) -> None:
    """A DOWNLINK carrying command `ident` that the robot acknowledged, received again byte for
    byte, must be dropped without a second ACK, the session going on (R-RSP-18): at once, the
    newest the robot has, and again once newer ones came, late and seen before (D-RSP-15: a late
    packet's occurrences are taken, a replayed one's are not; a robot that remembers only its
    newest number takes the second). Inconclusive without the first ACK."""
    command = first(probe.model, DeviceKind.COMMAND)
    if await acked(probe, raw, command, ident) is None:
        raise Inconclusive(f"no ACK of {command.name} #{ident} in the first place")
    original = raw.last
    for what in ("the replay", "the replay behind the newest"):
        await dropped_then_taken(ctx, probe, raw, lambda _: original, "R-RSP-18", what)


async def late_acked(
    probe: RspProbe, raw: RawSession, found: Device, ident: int, sequence: int, *, resume: int
) -> Datagram | None:
    """Send occurrence `ident` of command `found` in a DOWNLINK numbered `sequence`, older than
    the newest the robot has and never seen (again while the impairment spoils it), number our
    next packet `resume`, and return the robot's ACK of it: a late packet's occurrences are taken
    (D-RSP-15, R-RSP-26). None if no ACK came."""

    def late() -> None:
        raw.rewind(sequence)
        raw.downlink([occurrence(found, ident)])
        raw.rewind(resume)

    return await probe.answer_to(
        late, PacketType.ACK, where=lambda d: ident in d.acks(found.position)
    )


async def requested_uplinks(
    probe: RspProbe, raw: RawSession, devices: Iterable[Device], periods: int
) -> list[Datagram]:
    """Request `devices` (R-RSP-23) and return the UPLINKs of the `periods` periods after the
    robot took the request; Inconclusive if no UPLINK took it."""
    if await taken(probe, raw, flags(probe.model, *devices)) is None:
        raise Inconclusive("no UPLINK after the request")
    return await probe.received_within(periods * raw.period, PacketType.UPLINK)


async def hello_from_another(
    ctx: Context, probe: RspProbe, requirement: str, *, expected: str = ""
) -> Datagram:
    """The robot's answer (WELCOME or REFUSED) to the HELLO of another local system (a probe of
    its own, "second" in the transcript); Failed (`requirement`) if none comes. A session it
    opens ends with the case, as every session the robot opens for a probe."""
    other = await open_probe(ctx, robot=probe.robot, name="second")
    return await other.expect_answer_to(
        other.raw().hello,
        (PacketType.WELCOME, PacketType.REFUSED),
        requirement,
        expected=expected,
    )


async def another_welcomed(ctx: Context, probe: RspProbe, requirement: str, expected: str) -> None:
    """Another local system's HELLO must be answered WELCOME (`expected` says why, in the
    failure's text): the robot holds no session for `probe`, ended or never opened."""
    answer = await hello_from_another(ctx, probe, requirement)
    ctx.expect(
        answer.type is PacketType.WELCOME,
        expected,
        f"REFUSED {getattr(answer.body, 'reason', '')}",
        requirement,
    )


# -- an effector and its monitor, through the core's endpoint -------------------------------------


@dataclass(frozen=True, slots=True)
class Driven:
    """An effector the session's endpoint writes a value to, with every module it needs active
    and its monitor requested (`drive`): what the monitor reports of it (R-RSP-34)."""

    probe: RspProbe
    opened: events.SessionOpened
    effector: Device
    monitor: Device
    #: The value written: each field well away from 0 (`visible`).
    wanted: dict[str, Value]

    @property
    def field(self) -> Field:
        """The field the monitor is read by."""
        return self.effector.fields[0]

    def at_wanted(self, values: Mapping[str, Value]) -> bool:
        """Whether a report of the monitor has the value written."""
        return close_to(self.field, values.get(self.field.name), self.wanted[self.field.name])

    async def reached(self) -> bool:
        """Whether the monitor reports the value written within the probe's wait."""
        return await self.probe.state(self.monitor.name, self.at_wanted) is not None

    async def settled(self) -> None:
        """The monitor reporting the value written; Inconclusive if it never does (a case about
        what follows has nothing to start from)."""
        if not await self.reached():
            raise Inconclusive(f"{self.monitor.name} never reported {self.wanted}")

    async def moved(self, since: float) -> Mapping[str, Value] | None:
        """The first report already received from `since` (loop time) of the monitor away from
        the value written; None if none."""
        return await self.probe.state(
            self.monitor.name, lambda v: not self.at_wanted(v), since=since, wait=0
        )

    def latest(self) -> str:
        """The monitor's newest report, for a failure's text."""
        latest = self.probe.states.get(self.monitor.name)
        return "nothing" if latest is None else str(dict(latest[1]))


async def drive(ctx: Context, where: Callable[[Device], bool] = lambda _: True) -> Driven:
    """A session of the core's endpoint writing a `visible` value to an effector with a monitor
    (`monitored`: `where` holds of the effector; NotApplicable when the model has none)."""
    probe = await open_probe(ctx)
    model = probe.model
    effector, monitor = monitored(model, where)
    opened = await probe.open_session()
    wanted = {f.name: visible(f) for f in effector.fields}
    for module in modules_of(model, effector, monitor):
        probe.session.set_active(module.name, True)
    probe.session.write(effector.name, wanted)
    probe.session.set_active(monitor.name, True)
    return Driven(probe, opened, effector, monitor, wanted)
