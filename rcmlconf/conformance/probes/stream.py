"""An RCTP/2.0 data stream as a case drives it (specs/rctp-2.0.md §6): one UDP socket on the
control connection's local address, datagrams sent exactly as given or built with the core's
`push_packet`, received with bounded waits and decoded with the core's `pull_packet`.

Every datagram is recorded in the transcript twice: its bytes with its endpoints (`packet`, for
--capture) when it crosses the socket, and a note with its decoded summary when the case sends or
gets it. What came and the case has not taken waits in an inbox of INBOX datagrams at most (a
target that sends more before the case reads floods it: the oldest are dropped, and counted);
what the case took is kept as `DatagramLog`'s are, its first and its last. The case's impairment
(`Case.impairment`, seeded by --seed) sits between the socket and the case, one `rcmlconf.impair`
channel each way: what the case sends is impaired before it leaves, what arrives is impaired
before the case sees it. The target sees one source, the probe's port, as it must (R-RCTP-56): a
proxy in between would change it.
"""

from __future__ import annotations

import asyncio
import contextlib
import enum
import os
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

from rcmlconf.conformance.kept import Kept
from rcmlconf.conformance.probes.control import ControlProbe
from rcmlconf.conformance.probes.datagrams import ANSWER_TRIES, FIRST, LAST
from rcmlconf.conformance.probes.impaired import ImpairedPath
from rcmlconf.conformance.probes.inbound import Inbound
from rcmlconf.conformance.transcript import Address, Transcript, show
from rcmlconf.conformance.verdicts import Failed, HarnessError, Inconclusive
from rcmlconf.errors import ProtocolError, ValueTextError
from rcmlconf.impair import ImpairedChannel, Impairment, channel_pair
from rcmlconf.rcml.model import AccessNode, DataNode
from rcmlconf.rctp.bodies import ValuesCodec
from rcmlconf.rctp.datastream import (
    DataPayload,
    Direction,
    FlowMessage,
    FlowPayload,
    Message,
    Packet,
    Payload,
    UnknownPayload,
    ntp_from_unix,
    pull_packet,
    push_packet,
    stream_codec,
)
from rcmlconf.rctp.datastream.endpoint import micros
from rcmlconf.rctp.datastream.packets import MalformedFlowPayload
from rcmlconf.rctp.fields import Transport, parse_transport
from rcmlconf.rctp.targets import format_target
from rcmlconf.values.shown import values_text

if TYPE_CHECKING:
    from rcmlconf.conformance.context import Context

#: R-RCTP-39: a datagram of the target's that does not decode breaks the packet layout.
LAYOUT = "R-RCTP-39"
#: What a FLOW request waits for, unless said otherwise (R-RCTP-46).
ANSWERED = "R-RCTP-46"
#: Seconds between the sendings of a FLOW request under an impairment (`StreamProbe.ask`).
REPEAT = 0.25
#: Datagrams that came and wait for the case to take them, at most.
INBOX = 4096


@dataclass(frozen=True, slots=True)
class Datagram:
    """One datagram as the case got it (after the impairment)."""

    data: bytes
    source: Address
    #: The loop's time when the case got it.
    at: float
    #: Its packet, or why it is none (`pull_packet`'s error).
    packet: Packet | None
    error: ProtocolError | None
    #: Datagrams the impairment lost on the way in since the one before (`loss` only).
    lost_before: int = 0


@dataclass(frozen=True, slots=True)
class StreamSetUp:
    """A SETUP of a stream access answered 200, and what its `Transport` says."""

    access: AccessNode
    mode: str
    client_port: int
    #: The answer's `Transport`, parsed.
    transport: Transport
    #: Where the target sends from and takes packets at: its host and `server_port`.
    server: Address
    tag: int
    stream: int

    @property
    def target(self) -> str:
        return format_target(self.access.path)

    # D-RCTP-18: intervals and timeouts start at the RCML's, in seconds here; `micros` gives
    # FLOW's microseconds (D-RCTP-22).
    @property
    def read_interval(self) -> float | None:
        return self.access.read_interval

    @property
    def write_interval(self) -> float | None:
        return self.access.write_interval

    @property
    def read_timeout(self) -> float:
        return self.access.read_timeout

    @property
    def write_timeout(self) -> float:
        return self.access.write_timeout

    def micros(self, seconds: float | None) -> int:
        return micros(seconds or 0.0)


class StreamProbe:
    def __init__(
        self,
        transport: asyncio.DatagramTransport,
        transcript: Transcript,
        wait: float,
        impairment: Impairment | None = None,
        seed: int = 0,
        flow: int = 0,
    ) -> None:
        self._transport = transport
        self.transcript = transcript
        #: Seconds to wait for an answer (the case's timeout scale applied).
        self.wait = wait
        self.local: Address = transport.get_extra_info("sockname")[:2]
        self._loop = asyncio.get_running_loop()
        self._inbox: asyncio.Queue[Datagram] = asyncio.Queue(INBOX)
        #: Datagrams dropped from the full inbox, the oldest first.
        self.dropped = 0
        outward = inward = None
        if impairment is not None and not impairment.is_none:
            outward, inward = channel_pair(impairment, seed, flow)
            transcript.note(f"udp {self.local[0]}:{self.local[1]} impaired: {impairment}")
        self._out = ImpairedPath(outward, self._leave, self._loop)
        self._in = ImpairedPath(inward, self._deliver, self._loop)
        #: The next sequence number this side sends (R-RCTP-41: from a random start).
        self.sequence = int.from_bytes(os.urandom(2), "big")
        self._request_id = int.from_bytes(os.urandom(2), "big")
        #: The latest SETUP answered 200: where packets go, with what tag.
        self.set_up: StreamSetUp | None = None
        #: Every packet of the target's the case got, in order (its first and last).
        self.history: Kept[Datagram] = Kept(FIRST, LAST)
        self.closed = False
        self._codecs: dict[tuple[str, Direction], ValuesCodec[DataNode]] = {}
        #: The direction of the DATA that comes to this socket: the robot's (READ) for a case
        #: that plays the client, the client's (WRITE) for one that plays the server.
        self.inbound = Direction.READ

    @classmethod
    async def open(
        cls,
        host: str,
        transcript: Transcript,
        wait: float,
        impairment: Impairment | None = None,
        seed: int = 0,
        flow: int = 0,
    ) -> StreamProbe:
        loop = asyncio.get_running_loop()
        try:
            transport, protocol = await loop.create_datagram_endpoint(Inbound, local_addr=(host, 0))
        except OSError as error:
            raise HarnessError(f"cannot open a UDP socket on {host}: {error}") from None
        probe = cls(transport, transcript, wait, impairment, seed, flow)
        protocol.arrived, protocol.error = probe._arrived, probe._error
        transcript.note(f"udp socket {probe.local[0]}:{probe.local[1]}")
        return probe

    @property
    def port(self) -> int:
        return self.local[1]

    @property
    def impairment(self) -> Impairment | None:
        channel = self._out.channel
        return channel.impairment if channel is not None else None

    @property
    def channels(self) -> tuple[ImpairedChannel | None, ImpairedChannel | None]:
        """The impairment's channels, outward and inward (None without one), for their counts."""
        return self._out.channel, self._in.channel

    # -- setting up ----------------------------------------------------------------------------

    async def setup(
        self,
        control: ControlProbe,
        access: AccessNode,
        mode: str = "read",
        *,
        precondition: bool = True,
    ) -> StreamSetUp:
        """SETUP of `access` for this socket (`Transport: udp;client_port=P;mode=M`).

        The answer must be 200 with a `Transport` holding `server_port`, `tag` and `stream`
        (R-RCTP-38). When the case checks something else (`precondition`), an answer that is not
        that makes it inconclusive; otherwise it fails.
        """
        transport = Transport(client_port=self.port, mode=mode)
        answer = await control.request(
            "SETUP", format_target(access.path), [("Transport", str(transport))]
        )

        def wrong(actual: str) -> Exception:
            if precondition:
                return Inconclusive(f"SETUP of {access.path} (mode {mode}): {actual}")
            return Failed("R-RCTP-38", "200 with Transport: server_port, tag and stream", actual)

        if answer.status != 200:
            raise wrong(f"{answer.status} {answer.reason}")
        text = answer.headers.get("Transport")
        if text is None:
            raise wrong("200 without Transport")
        try:
            given = parse_transport(text)
        except ValueTextError as error:
            raise wrong(f"Transport: {text} ({error})") from None
        if given.server_port is None or given.tag is None or given.stream is None:
            raise wrong(f"Transport: {text}")
        set_up = StreamSetUp(
            access,
            mode,
            self.port,
            given,
            (control.peer[0], given.server_port),
            given.tag,
            given.stream,
        )
        self.set_up = set_up
        return set_up

    # -- sending -------------------------------------------------------------------------------

    def next_sequence(self) -> int:
        sequence = self.sequence
        self.sequence = (sequence + 1) & 0xFFFF
        return sequence

    @property
    def last_sequence(self) -> int:
        """The sequence number of the last packet `send_packet` numbered itself."""
        return (self.sequence - 1) & 0xFFFF

    def next_request_id(self) -> int:
        """D-RCTP-22: one more per new request, modulo 65,536."""
        request_id = self._request_id
        self._request_id = (request_id + 1) & 0xFFFF
        return request_id

    def _destination(self, to: Address | None) -> Address:
        if to is not None:
            return to
        if self.set_up is None:
            raise HarnessError("the stream probe sends before a SETUP named the server's port")
        return self.set_up.server

    def send(self, data: bytes, what: str = "", to: Address | None = None) -> None:
        """`data` exactly as given, to `to` (the set-up stream's server by default)."""
        if self.closed:
            raise HarnessError("the stream probe is closed")
        destination = self._destination(to)
        outbound = Direction.WRITE if self.inbound is Direction.READ else Direction.READ
        summary = what or self._describe(data, outbound)
        fate = self._out.put(data, destination)
        spoiled = f"  [{fate} by the impairment]" if fate else ""
        self.transcript.note(f"-> udp {destination[0]}:{destination[1]} {summary}{spoiled}")

    def packet_bytes(
        self,
        payloads: Sequence[Payload],
        *,
        sequence: int | None = None,
        tag: int | None = None,
        timestamp: int | None = None,
    ) -> bytes:
        """A packet of `payloads` (`push_packet`): the next sequence number, the session's
        tag and the time now unless given."""
        if tag is None:
            if self.set_up is None:
                raise HarnessError("a packet needs the session's tag: SETUP first")
            tag = self.set_up.tag
        if sequence is None:
            sequence = self.next_sequence()
        if timestamp is None:
            timestamp = ntp_from_unix(time.time())
        return push_packet(Packet(sequence, tag, timestamp, tuple(payloads)))

    def send_packet(
        self,
        payloads: Sequence[Payload],
        *,
        sequence: int | None = None,
        tag: int | None = None,
        timestamp: int | None = None,
        to: Address | None = None,
    ) -> bytes:
        """Build a packet (`packet_bytes`) and send it; its bytes."""
        data = self.packet_bytes(payloads, sequence=sequence, tag=tag, timestamp=timestamp)
        self.send(data, to=to)
        return data

    def send_flow(self, flow: FlowMessage, stream: int = 0, *, sequence: int | None = None) -> None:
        """One FLOW payload in a packet of its own (the next sequence number unless given)."""
        self.send_packet([FlowPayload(stream, flow)], sequence=sequence)

    def _leave(self, data: bytes, destination: Address, lost: int, _at: float) -> None:
        if self.closed:
            return
        self.transcript.packet("udp", self.local, destination, data)
        with contextlib.suppress(OSError):
            self._transport.sendto(data, destination)

    # -- receiving -----------------------------------------------------------------------------

    def _error(self, error: Exception) -> None:
        self.transcript.note(f"udp error: {error}")

    def _arrived(self, data: bytes, source: Address, at: float) -> None:
        if self.closed:
            return
        self.transcript.packet("udp", source, self.local, data)
        fate = self._in.put(data, source, at)
        if fate:
            self.transcript.note(f"<- udp {source[0]}:{source[1]} {fate} by the impairment")

    def _deliver(self, data: bytes, source: Address, lost: int, at: float) -> None:
        try:
            packet, error = pull_packet(data), None
        except ProtocolError as exc:
            packet, error = None, exc
        summary = _summary(data, packet, error, self._values(self.inbound))
        self.transcript.note(f"<- udp {source[0]}:{source[1]} {summary}")
        if self._inbox.full():
            self._inbox.get_nowait()
            self.dropped += 1
            if self.dropped == 1:
                self.transcript.note(
                    f"the stream probe holds {INBOX} datagrams the case has not taken: it drops"
                    " the oldest (counted when it closes)"
                )
        self._inbox.put_nowait(Datagram(data, source, at, packet, error, lost))

    async def datagram(self, wait: float | None = None) -> Datagram | None:
        """The next datagram, as it came; None when none comes within `wait` (the probe's)."""
        if not self._inbox.empty():
            return self._inbox.get_nowait()
        try:
            return await asyncio.wait_for(self._inbox.get(), self.wait if wait is None else wait)
        except TimeoutError:
            return None

    async def packet(self, wait: float | None = None, *, strict: bool = True) -> Datagram | None:
        """The next datagram, which must be a packet (R-RCTP-39); with `strict`, from the
        set-up stream's server port (R-RCTP-56) and with the session's tag (R-RCTP-39). None
        when none comes within `wait`."""
        found = await self.datagram(wait)
        if found is None:
            return None
        if found.error is not None:
            error = found.error
            raise Failed(
                error.rule or LAYOUT,
                "a packet of D-RCTP-19's layout",
                f"{error.reason} at byte {error.offset} of a datagram from"
                f" {found.source[0]}:{found.source[1]}",
            )
        assert found.packet is not None
        self.history.append(found)
        set_up = self.set_up
        if strict and set_up is not None:
            if found.source != set_up.server:
                raise Failed(
                    "R-RCTP-56",
                    f"packets from {set_up.server[0]}:{set_up.server[1]} (server_port)",
                    f"a packet from {found.source[0]}:{found.source[1]}",
                )
            if found.packet.tag != set_up.tag:
                raise Failed(
                    LAYOUT, f"the session's tag {set_up.tag:08x}", f"tag {found.packet.tag:08x}"
                )
        return found

    def drain(self) -> list[Datagram]:
        """Every datagram that came and the case has not taken, taken now unchecked (what was in
        flight before a PAUSE or STOP); packets among them go to `history`."""
        found: list[Datagram] = []
        while not self._inbox.empty():
            one = self._inbox.get_nowait()
            found.append(one)
            if one.packet is not None:
                self.history.append(one)
        return found

    async def packets(self, duration: float, *, strict: bool = True) -> Kept[Datagram]:
        """Every packet that comes within `duration` seconds (its first and last, all counted)."""
        deadline = self._loop.time() + duration
        found: Kept[Datagram] = Kept(FIRST, LAST)
        while (left := deadline - self._loop.time()) > 0:
            one = await self.packet(left, strict=strict)
            if one is not None:
                found.append(one)
        return found

    async def data(
        self, stream: int, wait: float | None = None, *, strict: bool = True
    ) -> tuple[Datagram, DataPayload] | None:
        """The next DATA payload of `stream` (packets without one are kept in `history`)."""
        deadline = self._loop.time() + (self.wait if wait is None else wait)
        while (left := deadline - self._loop.time()) > 0:
            one = await self.packet(left, strict=strict)
            if one is None:
                return None
            assert one.packet is not None
            for payload in one.packet.payloads:
                if isinstance(payload, DataPayload) and payload.stream == stream:
                    return one, payload
        return None

    async def answer(
        self, request_id: int, wait: float | None = None, *, strict: bool = True
    ) -> tuple[Datagram, FlowMessage] | None:
        """The next ACK or NACK with `request_id`; None when none comes within `wait`. A FLOW
        body of the target's that breaks its layout fails R-RCTP-52."""
        deadline = self._loop.time() + (self.wait if wait is None else wait)
        while (left := deadline - self._loop.time()) > 0:
            one = await self.packet(left, strict=strict)
            if one is None:
                return None
            found = answers(one)
            for flow in found:
                if flow.request_id == request_id:
                    return one, flow
        return None

    async def ask(
        self,
        build: Callable[[int], FlowMessage],
        stream: int = 0,
        *,
        wait: float | None = None,
        requirement: str = ANSWERED,
    ) -> FlowMessage:
        """Send a FLOW request (`build` makes it from the next request id) and return its ACK or
        NACK; none within `wait` fails `requirement`."""
        request = build(self.next_request_id())
        got = await self.answer_to(
            lambda: self.send_flow(request, stream), request.request_id, wait
        )
        if got is None:
            seconds = self.wait if wait is None else wait
            raise Failed(
                requirement,
                f"an ACK or NACK of request {request.request_id}",
                f"nothing within {seconds:g} s",
            )
        return got[1]

    async def answer_to(
        self, send: Callable[[], object], request_id: int, wait: float | None = None
    ) -> tuple[Datagram, FlowMessage] | None:
        """Call `send` (it sends a packet holding request `request_id`) and return the ACK or
        NACK of that id (`answer`); None when none comes within `wait`. Under an impairment the
        packet goes again every REPEAT seconds until answered, as a requester whose request or
        answer was lost sends it again (R-RCTP-46: a repeated id gets the answer already
        given)."""
        deadline = self._loop.time() + (self.wait if wait is None else wait)
        impaired = self._out.channel is not None
        for _ in range(ANSWER_TRIES):
            send()
            left = deadline - self._loop.time()
            got = await self.answer(request_id, min(left, REPEAT) if impaired else left)
            if got is not None or not impaired or self._loop.time() >= deadline:
                return got
        return None

    def _describe(self, data: bytes, direction: Direction) -> str:
        """A datagram in one line: its header and payloads (a DATA payload's values, of the
        set-up stream's `direction`), or why it is no packet."""
        try:
            packet, error = pull_packet(data), None
        except ProtocolError as exc:
            packet, error = None, exc
        return _summary(data, packet, error, self._values(direction))

    def _values(self, direction: Direction) -> Callable[[DataPayload], str] | None:
        """What a DATA payload of the set-up stream holds, for the transcript."""
        set_up = self.set_up
        if set_up is None:
            return None
        key = (set_up.access.path, direction)
        codec = self._codecs.get(key)
        if codec is None:
            codec = self._codecs[key] = stream_codec(set_up.access, direction)

        def values(payload: DataPayload) -> str:
            if payload.stream != set_up.stream:
                return ""
            try:
                decoded = codec.decode(payload.body)
            except ProtocolError as error:
                return f" (not {direction.name.lower()} values: {error.reason})"
            return " " + ", ".join(values_text(codec.nodes, decoded))

        return values

    def close(self) -> None:
        if not self.closed:
            if self.dropped:
                self.transcript.note(f"the stream probe dropped {self.dropped} datagrams unread")
            self.closed = True
            self._out.close()
            self._in.close()
            self._transport.close()


def answers(datagram: Datagram) -> list[FlowMessage]:
    """The FLOW ACKs and NACKs of a packet of the target's; a broken FLOW body of its fails
    R-RCTP-52."""
    found: list[FlowMessage] = []
    assert datagram.packet is not None
    for payload in datagram.packet.payloads:
        if isinstance(payload, MalformedFlowPayload):
            raise Failed(
                payload.rule,
                "FLOW bodies of D-RCTP-22's layout",
                f"{payload.reason} at byte {payload.offset} of a packet of the target's",
            )
        if isinstance(payload, FlowPayload) and payload.flow.message is not Message.REQUEST:
            found.append(payload.flow)
    return found


async def open_stream(ctx: Context, control: ControlProbe, flow: int = 0) -> StreamProbe:
    """A data-stream socket for the case, on the control connection's local address (where the
    target sends, D-RCTP-28), under the case's impairment (`flow` numbers the case's sockets
    for the impairment's seeds), closed with the case. The impairment is --impair's, else the
    case's (`Context.impairment`)."""
    probe = await StreamProbe.open(
        control.local[0], ctx.transcript, ctx.wait, ctx.impairment, ctx.impairment_seed(), flow
    )
    ctx.on_close(probe.close)
    ctx.watch(*probe.channels)
    return probe


def _summary(
    data: bytes,
    packet: Packet | None,
    error: ProtocolError | None,
    values: Callable[[DataPayload], str] | None = None,
) -> str:
    if packet is None:
        reason = f"{error.reason} at byte {error.offset}" if error is not None else "?"
        return f"not a packet ({reason}): {show(data)}"
    parts = ", ".join(_payload(p, values) for p in packet.payloads)
    return f"seq {packet.sequence} tag {packet.tag:08x} [{parts}]"


def _payload(payload: Payload, values: Callable[[DataPayload], str] | None = None) -> str:
    if isinstance(payload, DataPayload):
        shown = values(payload) if values is not None else ""
        return f"DATA s{payload.stream} {len(payload.body)} B{shown}"
    if isinstance(payload, FlowPayload):
        return f"FLOW s{payload.stream} {flow_text(payload.flow)}"
    if isinstance(payload, UnknownPayload):
        return f"type {payload.type} s{payload.stream} {len(payload.body)} B"
    return f"FLOW s{payload.stream} malformed ({payload.reason}) {show(payload.body)}"


def flow_text(flow: FlowMessage | None) -> str:
    """A FLOW message as the exchange shows it (`IntervalSetAck id 7 (direction=read,
    interval=16000)`), or `none`: what a failure reports it got, never a Python repr."""
    if flow is None:
        return "none"
    fields = ", ".join(
        f"{name}={_field(getattr(flow, name))}"
        for name in getattr(flow, "__dataclass_fields__", {})
        if name != "request_id"
    )
    return f"{type(flow).__name__} id {flow.request_id}" + (f" ({fields})" if fields else "")


def _field(value: object) -> str:
    return value.name.lower() if isinstance(value, enum.Enum) else str(value)
