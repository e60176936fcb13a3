"""The data stream the harness plays to a client running D-RCTP-31's scenario (§6): while the
stream plays it sends DATA of the readable nodes at the read interval (D-RCTP-20), answers the
client's FLOW requests as the owner of the read interval and the write timeout would
(D-RCTP-22; a heartbeat by the played robot's clock, `skew` seconds off the harness's), and keeps
every datagram of the client's for the cases to judge. A case may send packets of its own through
`probe` (a stale sequence number, values out of range) and stop the played DATA (`sending`)."""

from __future__ import annotations

import asyncio
import contextlib
import os
import time
from collections.abc import Mapping
from typing import TYPE_CHECKING

from rcmlconf.conformance.kept import Kept
from rcmlconf.conformance.probes.control import ControlProbe
from rcmlconf.conformance.probes.datagrams import FIRST, LAST
from rcmlconf.conformance.probes.stream import Datagram, StreamProbe, StreamSetUp, open_stream
from rcmlconf.conformance.verdicts import Failed
from rcmlconf.rcml.model import AccessNode
from rcmlconf.rctp.datastream import (
    DataPayload,
    Direction,
    FlowMessage,
    FlowPayload,
    HeartbeatAck,
    HeartbeatRequest,
    IntervalGet,
    IntervalGetAck,
    Message,
    Nack,
    NackReason,
    TimeoutGet,
    TimeoutGetAck,
    ntp_from_unix,
    stream_codec,
)
from rcmlconf.rctp.datastream.endpoint import micros
from rcmlconf.rctp.datastream.packets import MalformedFlowPayload
from rcmlconf.rctp.fields import Transport
from rcmlconf.values import Value

if TYPE_CHECKING:
    from rcmlconf.conformance.context import Context

#: The one stream id the played server gives (D-RCTP-28 numbers from 1).
STREAM_ID = 1


class PlayedStream:
    def __init__(self, probe: StreamProbe, control: ControlProbe, values: Mapping[str, Value]):
        self.probe = probe
        self._control = control
        self._values = values
        #: D-RCTP-19: random and unguessable.
        self.tag = int.from_bytes(os.urandom(4), "big")
        self.access: AccessNode | None = None
        self.mode = "read"
        self.client_port = 0
        self.playing = False
        #: Whether the played server sends DATA while the stream plays (a case may stop it).
        self.sending = True
        #: Seconds the played robot's clock is ahead of the harness's (its heartbeat ACKs).
        self.skew = 0.0
        #: Every datagram of the client's, in order (its first and last).
        self.received: Kept[Datagram] = Kept(FIRST, LAST)
        #: The FLOW requests of the client's, with the datagram each came in (likewise).
        self.flow_requests: Kept[tuple[Datagram, FlowMessage]] = Kept(FIRST, LAST)
        #: The client's FLOW bodies that break D-RCTP-22's layout (R-RCTP-52) (likewise).
        self.malformed: Kept[MalformedFlowPayload] = Kept(FIRST, LAST)
        self._tasks: list[asyncio.Task[None]] = []
        self._asked: dict[int, asyncio.Future[FlowMessage]] = {}

    @classmethod
    async def open(
        cls, ctx: Context, control: ControlProbe, values: Mapping[str, Value]
    ) -> PlayedStream:
        probe = await open_stream(ctx, control)
        probe.inbound = Direction.WRITE
        stream = cls(probe, control, values)
        stream._tasks = [
            asyncio.ensure_future(stream._read()),
            asyncio.ensure_future(stream._send()),
        ]
        ctx.on_close(stream.close)
        if (listener := ctx.target.clients) is not None:
            ctx.on_close(lambda: listener.stream_starts.extend(stream.first_sequence()))
        return stream

    def set_up(self, access: AccessNode, asked: Transport) -> None:
        """A SETUP of the client's (D-RCTP-28: the latest one's client port is where packets
        go)."""
        assert asked.client_port is not None
        self.access, self.mode, self.client_port = access, asked.mode, asked.client_port
        client = (self._control.peer[0], asked.client_port)
        self.probe.set_up = StreamSetUp(
            access, asked.mode, self.probe.port, self.transport, client, self.tag, STREAM_ID
        )

    @property
    def transport(self) -> Transport:
        """The SETUP answer's `Transport` (D-RCTP-18)."""
        return Transport(
            client_port=self.client_port,
            mode=self.mode,
            server_port=self.probe.port,
            tag=self.tag,
            stream=STREAM_ID,
        )

    def robot_time(self) -> int:
        """Now by the played robot's clock, in NTP format."""
        return ntp_from_unix(time.time() + self.skew)

    # -- what the client sent ----------------------------------------------------------------

    def first_sequence(self) -> list[int]:
        """The sequence number of the client's first packet, if one came."""
        return [one.packet.sequence for one in self.received[:1] if one.packet is not None]

    def data(self) -> list[tuple[Datagram, DataPayload]]:
        """Every DATA payload of the client's, with its datagram."""
        return [
            (one, payload)
            for one in self.received
            if one.packet is not None
            for payload in one.packet.payloads
            if isinstance(payload, DataPayload)
        ]

    # -- the loops ------------------------------------------------------------------------------

    async def _send(self) -> None:
        while True:
            access = self.access
            interval = access.read_interval if access is not None else None
            if (
                access is not None
                and interval
                and self.playing
                and self.sending
                and self.mode in ("read", "both")
            ):
                codec = stream_codec(access, Direction.READ)
                body = codec.encode({n.name: self._values[n.path] for n in codec.nodes})
                self.probe.send_packet([DataPayload(STREAM_ID, body)])
            await asyncio.sleep(interval or 0.05)

    async def _read(self) -> None:
        while True:
            one = await self.probe.datagram(3600.0)
            if one is None:
                continue
            self.received.append(one)
            if one.packet is None:
                continue
            for payload in one.packet.payloads:
                if isinstance(payload, MalformedFlowPayload):
                    self.malformed.append(payload)
                if not isinstance(payload, FlowPayload):
                    continue
                flow = payload.flow
                if flow.message is Message.REQUEST:
                    self.flow_requests.append((one, flow))
                    answer = self._answer(flow, one.at)
                    self.probe.send_packet([FlowPayload(payload.stream, answer)])
                elif (waiter := self._asked.get(flow.request_id)) and not waiter.done():
                    waiter.set_result(flow)

    async def ask(self, request: FlowMessage, stream: int = 0) -> FlowMessage:
        """Send a FLOW request of the played server's and return the client's ACK or NACK;
        none within the probe's wait fails R-RCTP-46."""
        return await self._ask(FlowPayload(stream, request), request.request_id)

    async def ask_broken(self, body: bytes, request_id: int, stream: int = 0) -> FlowMessage:
        """`ask` with a FLOW body of the case's own, broken on purpose, whose request id is
        `request_id`."""
        return await self._ask(MalformedFlowPayload(stream, body, "sent broken", 0), request_id)

    async def _ask(
        self, payload: FlowPayload | MalformedFlowPayload, request_id: int
    ) -> FlowMessage:
        waiter: asyncio.Future[FlowMessage] = asyncio.get_running_loop().create_future()
        self._asked[request_id] = waiter
        self.probe.send_packet([payload])
        try:
            return await asyncio.wait_for(waiter, self.probe.wait)
        except TimeoutError:
            if self.malformed:  # the answer may be there, in a body no reader can take
                broken = self.malformed[-1]
                raise Failed(
                    "R-RCTP-52",
                    f"an ACK or NACK of request {request_id} in D-RCTP-22's layout",
                    f"a FLOW body that breaks it: {broken.reason} ({broken.body.hex(' ')})",
                ) from None
            raise Failed(
                "R-RCTP-46",
                f"an ACK or NACK of request {request_id}",
                f"nothing within {self.probe.wait:g} s",
            ) from None
        finally:
            self._asked.pop(request_id, None)

    def _answer(self, flow: FlowMessage, arrived: float) -> FlowMessage:
        """D-RCTP-22's answer of the owner of the read interval and the write timeout."""
        access = self.access
        if isinstance(flow, HeartbeatRequest):
            # T2 is when it came, by the loop's clock turned to the robot's; T3 now.
            late = asyncio.get_running_loop().time() - arrived
            t2 = ntp_from_unix(time.time() - late + self.skew)
            return HeartbeatAck(flow.request_id, flow.t1, t2, self.robot_time())
        if access is not None and isinstance(flow, IntervalGet):
            seconds = access.read_interval if flow.direction is Direction.READ else None
            seconds = seconds or access.write_interval
            return IntervalGetAck(flow.request_id, flow.direction, micros(seconds or 0.0))
        if access is not None and isinstance(flow, TimeoutGet):
            seconds = (
                access.read_timeout if flow.direction is Direction.READ else access.write_timeout
            )
            return TimeoutGetAck(flow.request_id, flow.direction, micros(seconds))
        return Nack(flow.request_id, int(getattr(flow, "operation", 0)), NackReason.NOT_PERMITTED)

    def close(self) -> None:
        for task in self._tasks:
            task.cancel()
        with contextlib.suppress(Exception):
            self.probe.close()
