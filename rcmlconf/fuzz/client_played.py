"""The server the fuzzer plays to an RCTP/2.0 client (D-FUZZ-8): the reference server, whose
session of the case's client sends the case's steps once the client enters the case's state.

The reference session answers the client's scenario as a conforming server does; `Played`
watches for the request that enters the state, swaps its answer for the case's first step
when that step is an answer, sends the steps of the server's own, and then, at `probe`, the
liveness probe: a BYE, which ends the run. A request of the server's goes through the core as
the valid request it began from (so the core numbers it and takes its answer), and leaves as
the mutated bytes. What the session saw is kept for the judgement (`Seen`).
"""

from __future__ import annotations

import asyncio
import contextlib
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TypeVar

from rcmlconf.errors import ProtocolError, ValueTextError
from rcmlconf.fuzz.client_cases import ANSWER, DATA, HEARTBEAT_KINDS, Entry
from rcmlconf.fuzz.mutate import ID_AT, T1_AT, T2_AT
from rcmlconf.fuzz.owed import FRAMING_STATUSES
from rcmlconf.fuzz.steps import CSEQ, SESSION, TRANSPORT, Step, TestCase
from rcmlconf.pcap.writer import Payload
from rcmlconf.rcml.model import RcmlDocument
from rcmlconf.rctp.connection import RequestReceived, ResponseReceived
from rcmlconf.rctp.datastream.endpoint import Address
from rcmlconf.rctp.datastream.flow import Direction, HeartbeatAck, IntervalGet
from rcmlconf.rctp.datastream.packets import (
    HEADER,
    PAYLOAD_HEADER,
    FlowPayload,
    body_offsets,
    pull_packet,
)
from rcmlconf.rctp.errors import LocalProtocolError, RemoteProtocolError
from rcmlconf.rctp.fields import parse_session
from rcmlconf.rctp.messages import Request, Response
from rcmlconf.rctp.reader import MessageReader
from rcmlconf.rctp.states import StreamState
from rcmlconf.rctp.targets import parse_target
from rcmlconf.reference.drivers import choose_driver
from rcmlconf.reference.server.adapter import ReferenceServer, ServerSettings
from rcmlconf.reference.server.robot import Robot
from rcmlconf.reference.server.session import ServerSession

T = TypeVar("T")
PLAYING = StreamState.PLAYING
#: Header fields of a datagram the played server fills in (D-FUZZ-8), unless the step's
#: mutation changed them: sequence, tag and timestamp (bytes 2 to 16), stream (byte 17).
_KEPT = {"data-sequence": (2, 4), "data-tag": (4, 8)}


@dataclass(slots=True)
class Seen:
    """What one case's session saw and did, for the judgement."""

    case: TestCase
    entry: Entry
    #: The state's request came, and the steps went (the loop's time.monotonic()).
    reached: float | None = None
    #: Why the client may end its run after what it was sent (D-FUZZ-8), or None.
    may_end: str | None = None
    #: The client closed (or reset) the connection; the session is over.
    client_closed: bool = False
    ended: threading.Event = field(default_factory=threading.Event)
    #: The server's requests the client had not answered when the session ended, for people.
    unanswered: list[str] = field(default_factory=list)
    #: The client's answers to the server's requests, in order: their status codes.
    statuses: list[int] = field(default_factory=list)
    #: The client answered 400, 413, 414 or 431: it found a message unframeable (D-RCTP-10).
    refused_framing: bool = False
    payloads: list[Payload] = field(default_factory=list)


def _framed(data: bytes) -> Request | Response | None:
    """The one whole message `data` holds, or None when it holds no whole message."""
    reader = MessageReader()
    reader.feed(data)
    try:
        message = reader.next_message()
    except RemoteProtocolError:
        return None
    return message if message is not None and not reader.buffered else None


class PlayedSession(ServerSession):
    def __init__(
        self, robot: Robot[ServerSession], peer: Address, now: float, seen: Seen, us: Address
    ) -> None:
        super().__init__(robot, peer, now)
        self.seen = seen
        self.us = us
        self._out = bytearray()
        self._datagrams: list[bytes] = []
        #: Steps that answer the client's next heartbeats (D-FUZZ-8), oldest first.
        self._acks: list[Step] = []
        #: The client's messages read again, for the answers the core cannot match to a request.
        self._theirs: MessageReader | None = MessageReader()

    # -- what the client sends ---------------------------------------------------------------

    def receive_data(self, data: bytes, now: float) -> None:
        if data:
            self._record("tcp", self.peer, self.us, data)
            self._read_theirs(data)
        else:
            self.seen.client_closed = not self.finished
        super().receive_data(data, now)

    def receive_datagram(self, data: bytes, addr: Address, now: float) -> None:
        self._record("udp", addr, (self.us[0], self.robot.data_port), data)
        super().receive_datagram(data, addr, now)

    def _read_theirs(self, data: bytes) -> None:
        reader = self._theirs
        if reader is None:
            return
        reader.feed(data)
        try:
            while (message := reader.next_message()) is not None:
                if isinstance(message, Response) and message.status in FRAMING_STATUSES:
                    self.seen.refused_framing = True
        except RemoteProtocolError:
            self._theirs = None  # the core's own reader ends the connection on it

    def _answered(self, event: ResponseReceived, now: float) -> None:
        self.seen.statuses.append(event.response.status)
        super()._answered(event, now)

    def _end(self) -> None:
        if not self.finished:
            self.seen.unanswered = [f"{r.method} {r.target}" for r in self.conn.requests_unanswered]
            self.seen.ended.set()
        super()._end()

    # -- what it is sent ---------------------------------------------------------------------

    def data_to_send(self) -> bytes:
        data = bytes(self._out) + super().data_to_send()
        self._out.clear()
        if data:
            self._record("tcp", self.us, self.peer, data)
        return data

    def datagrams_to_send(self, now: float) -> tuple[list[bytes], Address | None]:
        datagrams, peer = super().datagrams_to_send(now)
        datagrams = [*self._datagrams, *map(self._answer_heartbeat, datagrams)]
        self._datagrams.clear()
        if peer is not None:
            for datagram in datagrams:
                self._record("udp", (self.us[0], self.robot.data_port), peer, datagram)
        return datagrams, peer

    def _answer(self, event: RequestReceived, now: float) -> None:
        self._out += super().data_to_send()
        super()._answer(event, now)
        if self.seen.reached is not None or not self._enters(event.request):
            return
        reply = super().data_to_send()
        steps = list(self.seen.case.steps)
        if steps and steps[0].kind.startswith(ANSWER):
            reply = self._fill_answer(steps.pop(0), event.request, reply)
        self._out += reply
        self.seen.reached = time.monotonic()
        for step in steps:
            if self.seen.may_end is not None or self.finished:
                break
            self._send(step, now)

    def _enters(self, request: Request) -> bool:
        entry = self.seen.entry
        if request.method != entry.method:
            return False
        if entry.method == "GO" and self.conn.streams.get(entry.path or "") is not PLAYING:
            return False  # GO refused: the access does not play
        if entry.path is None:
            return True
        try:
            return parse_target(request.target).path == entry.path
        except ValueTextError:
            return False

    def _fill_answer(self, step: Step, request: Request, valid: bytes) -> bytes:
        """The step's answer with the run's CSeq, Session and Transport; and whether the
        client may end its run on it (D-FUZZ-8)."""
        given = _framed(valid)
        transport = given.headers.get("Transport") if isinstance(given, Response) else None
        data = (
            step.data.replace(CSEQ, (request.headers.get("CSeq") or "0").encode("latin-1"))
            .replace(SESSION, (self.id or "none").encode("latin-1"))
            .replace(TRANSPORT, (transport or "").encode("latin-1"))
        )
        sent = _framed(data)
        if not isinstance(sent, Response):
            self.seen.may_end = "D-RCTP-10: not one whole answer"
        elif sent.headers.get("CSeq") != request.headers.get("CSeq"):
            self.seen.may_end = "R-RCTP-12: an answer to none of its requests"
        elif request.method == "CONNECT":
            try:
                if sent.status != 200:
                    raise ValueTextError(f"status {sent.status}")
                parse_session(sent.headers.get("Session") or "")
            except ValueTextError as error:
                self.seen.may_end = f"D-RCTP-31: CONNECT not answered with a session ({error})"
        return data

    def _send(self, step: Step, now: float) -> None:
        if step.kind in HEARTBEAT_KINDS:
            self._acks.append(step)  # sent in place of the ACK of the client's next heartbeat
            return
        if step.channel == "data":
            self._send_datagram(step, now)
            return
        origin = _framed(step.origin.replace(SESSION, (self.id or "none").encode("latin-1")))
        if not isinstance(origin, Request):
            return
        headers = [
            (name, value)
            for name, value in origin.headers
            if name.lower() not in ("cseq", "session", "content-length")
        ]
        self._out += super().data_to_send()
        try:
            request = self.conn.send_request(
                origin.method, origin.target, headers, origin.body, now=now
            )
        except (ProtocolError, LocalProtocolError):
            return
        super().data_to_send()  # the valid bytes: the mutated ones leave instead
        data = step.data.replace(CSEQ, (request.headers.get("CSeq") or "0").encode("latin-1"))
        data = data.replace(SESSION, (self.id or "none").encode("latin-1"))
        self._out += data
        if not isinstance(_framed(data), Request):
            # It cannot be framed, or it is not whole and the client waits for the rest.
            self.seen.may_end = "D-RCTP-10: not one whole request"

    def _send_datagram(self, step: Step, now: float) -> None:
        """The step as the server's next datagram: its header's numbers those of a valid one
        the endpoint makes in its place (a FLOW request the client must answer)."""
        endpoint = self.endpoint
        if endpoint is None or not endpoint.streams:
            return
        stream = next(iter(endpoint.streams))
        self._datagrams += super().datagrams_to_send(now)[0]
        try:
            endpoint.request(lambda rid: IntervalGet(rid, Direction.READ), stream, now)
        except (ProtocolError, LocalProtocolError):
            return
        carriers = super().datagrams_to_send(now)[0]
        if not carriers:
            return
        carrier, data = carriers[-1], bytearray(step.data)
        self._datagrams += carriers[:-1]
        for start, end in ((2, 4), (4, 8), (8, 16)):
            if _KEPT.get(step.kind) != (start, end) and len(data) >= end:
                data[start:end] = carrier[start:end]
        if step.tagged and len(data) >= 18 and data[17] == 1:
            data[17] = stream
        self._datagrams.append(bytes(data))

    def _answer_heartbeat(self, datagram: bytes) -> bytes:
        """The datagram with the ACK of the client's heartbeat swapped for the oldest held
        step's, the request's id and T1 filled in (T1's bits flipped by `heartbeat-echo`)."""
        if not self._acks:
            return datagram
        try:
            packet = pull_packet(datagram)
        except ProtocolError:
            return datagram
        for payload, at in zip(packet.payloads, body_offsets(packet), strict=True):
            if isinstance(payload, FlowPayload) and isinstance(payload.flow, HeartbeatAck):
                step = self._acks.pop(0)
                body = bytearray(step.data[HEADER.size + PAYLOAD_HEADER.size :])
                body[ID_AT:T1_AT] = payload.flow.request_id.to_bytes(2, "big")
                t1 = payload.flow.t1
                if step.kind == DATA + "heartbeat-echo":
                    t1 ^= int.from_bytes(body[T1_AT:T2_AT], "big")
                body[T1_AT:T2_AT] = t1.to_bytes(8, "big")
                return datagram[:at] + bytes(body) + datagram[at + len(body) :]
        return datagram

    def send_probe(self, now: float) -> None:
        """D-FUZZ-8's liveness probe: a BYE of the server's, which ends the run once answered."""
        if self.finished or self.seen.may_end is not None:
            return
        with contextlib.suppress(ProtocolError, LocalProtocolError):
            self.conn.send_request("BYE", "*", [("Reason", "shutdown")], now=now)

    def _record(self, transport: str, source: Address, destination: Address, data: bytes) -> None:
        if len(self.seen.payloads) < 10_000:
            self.seen.payloads.append(Payload(time.time(), transport, source, destination, data))


class _Server(ReferenceServer):
    """The reference server whose next connection gets the case's session (`seen`)."""

    seen: Seen | None = None

    def new_session(self, peer: Address, now: float) -> ServerSession:
        seen, self.seen = self.seen, None
        if seen is None:  # a second connection of the case's client: served, not fuzzed
            return super().new_session(peer, now)
        return PlayedSession(self.robot, peer, now, seen, (self.settings.host, self.port))


class PlayedServer:
    """The played server on its own thread and event loop, while the fuzzer waits on its own."""

    def __init__(self, rcml: Path, model: RcmlDocument, host: str, port: int) -> None:
        settings = ServerSettings(host=host, port=port, http_port=port + 1)
        self._server = _Server(rcml, model, choose_driver("auto", model), settings)
        self.loop = asyncio.new_event_loop()
        self._thread = threading.Thread(target=self.loop.run_forever, daemon=True)
        self._thread.start()
        asyncio.run_coroutine_threadsafe(self._server.start(), self.loop).result(10)

    def expect(self, seen: Seen) -> None:
        """The next connection is the case's."""
        self._call(lambda: setattr(self._server, "seen", seen))

    def forget(self) -> None:
        self._call(lambda: setattr(self._server, "seen", None))

    def probe(self) -> None:
        """Send the probe on the case's session, if it is still open."""

        def send() -> None:
            for session, control in tuple(self._server.controls.items()):
                if isinstance(session, PlayedSession):
                    session.send_probe(self.loop.time())
                    self._server.flush(control)

        self._call(send)

    def unanswered(self, seen: Seen) -> list[str]:
        """The server's requests the case's client has not answered yet."""

        def read() -> list[str]:
            for session in self._server.controls:
                if isinstance(session, PlayedSession) and session.seen is seen:
                    return [f"{r.method} {r.target}" for r in session.conn.requests_unanswered]
            return list(seen.unanswered)

        return self._call(read)

    def _call(self, function: Callable[[], T]) -> T:
        async def run() -> T:
            return function()

        return asyncio.run_coroutine_threadsafe(run(), self.loop).result(10)

    def close(self) -> None:
        try:
            asyncio.run_coroutine_threadsafe(self._server.stop(), self.loop).result(10)
        finally:
            self.loop.call_soon_threadsafe(self.loop.stop)
            self._thread.join(5)
