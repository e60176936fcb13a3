"""The client end of one RCTP/2.0 session, without I/O: the operator console's protocol.

Over the control connection's core (`rctp.connection`) and the data stream's (`rctp.datastream`)
it adds what a client must know of the robot: which streams it set up and with what transport,
the values it writes on each (held and sent every interval, D-RCTP-20), and the answers it owes
the server's WRITE and STOP (R-RCTP-24). Everything the application should hear of comes out of
`next_event` as one of the classes below.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass

from rcmlconf.errors import ProtocolError, ValueTextError
from rcmlconf.rcml.model import AccessNode, AccessType, RcmlDocument
from rcmlconf.rctp.bodies import ValuesCodec
from rcmlconf.rctp.connection import (
    ConnectionClosed,
    KeepAliveDue,
    ProtocolFailure,
    RequestReceived,
    RequestRejected,
    ResponseReceived,
    SessionEnded,
)
from rcmlconf.rctp.datastream.clock import ClockEstimate
from rcmlconf.rctp.datastream.endpoint import HEARTBEAT_EVERY, Endpoint, Stream
from rcmlconf.rctp.datastream.events import ClockUpdated, StreamTimedOut, ValuesReceived
from rcmlconf.rctp.datastream.flow import Direction
from rcmlconf.rctp.errors import LocalProtocolError
from rcmlconf.rctp.fields import parse_nodes, parse_transport
from rcmlconf.rctp.messages import Request, Response
from rcmlconf.rctp.states import Role
from rcmlconf.rctp.targets import format_target, parse_target
from rcmlconf.reference.ends import SessionEnd
from rcmlconf.values import Value

# -- what the application hears ----------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class Answered:
    """The response to one of this side's requests."""

    request: Request
    response: Response
    #: What in a success answer this side could not use (a SETUP's Transport without a tag).
    problem: str | None = None


@dataclass(frozen=True, slots=True)
class ServerRequest:
    """The server's WRITE, STOP or BYE (D-RCTP-12), already answered (`status`)."""

    method: str
    path: str
    status: int
    #: A WRITE's values by node name (a data-change event, D-RCTP-27).
    values: Mapping[str, Value] | None = None
    #: `Reason` of a STOP or BYE.
    reason: str | None = None


@dataclass(frozen=True, slots=True)
class StreamValues:
    """A stream's newest values from the robot (D-RCTP-20)."""

    path: str
    values: Mapping[str, Value]
    #: When the robot sent them, by the robot's clock (64-bit NTP).
    sent: int


@dataclass(frozen=True, slots=True)
class StreamLost:
    """No DATA from the robot for the stream's read timeout (D-RCTP-23)."""

    path: str


@dataclass(frozen=True, slots=True)
class ClockEstimated:
    estimate: ClockEstimate


@dataclass(frozen=True, slots=True)
class Closed:
    """The session and its connection are over; `reason` says why."""

    reason: str


ClientEvent = Answered | ServerRequest | StreamValues | StreamLost | ClockEstimated | Closed
#: What a stream writes every interval: values held, or a function asked for them each time.
WriteSource = Mapping[str, Value] | Callable[[], Mapping[str, Value]]


class ClientSession(SessionEnd):
    def __init__(
        self,
        model: RcmlDocument | None,
        server_host: str,
        now: float,
        *,
        unix_offset: float = 0.0,
        first_sequence: int = 0,
        heartbeat_every: float = HEARTBEAT_EVERY,
    ) -> None:
        """`model` is the robot's RCML, without which values stay bytes and nothing streams;
        `heartbeat_every` the seconds between heartbeats while a stream plays (D-RCTP-24)."""
        super().__init__(Role.CLIENT, now)
        self.model = model
        self.server_host = server_host
        self._unix_offset = unix_offset
        self._first_sequence = first_sequence
        self._heartbeat_every = heartbeat_every
        #: Stream access path -> stream id, for the streams set up.
        self.streams: dict[str, int] = {}
        #: The body this side writes on each stream, by stream id, made each interval.
        self._writes: dict[int, Callable[[], bytes]] = {}
        #: Stream access path -> the newest values applied from the robot (D-RCTP-20, D-RCTP-21).
        self.received: dict[str, Mapping[str, Value]] = {}
        self._events: deque[ClientEvent] = deque()
        #: The target of CONNECT (D-RCTP-3), which its refreshes repeat.
        self.site_path = "/"
        self.closed = False

    # -- requests ----------------------------------------------------------------------------

    def send(
        self,
        method: str,
        path: str,
        headers: Iterable[tuple[str, str]] = (),
        body: bytes = b"",
        *,
        now: float,
    ) -> Request:
        """A request of `path` (`*`, `/` or a node path); CSeq and Session are added."""
        if method == "CONNECT":
            self.site_path = path
        return self.conn.send_request(method, format_target(path), headers, body, now=now)

    def access(self, path: str) -> AccessNode:
        node = self.model.node(path) if self.model is not None else None
        if not isinstance(node, AccessNode):
            raise LocalProtocolError(f"{path} is not an access node of the robot's RCML")
        return node

    def write_values(self, path: str, values: WriteSource) -> None:
        """The values to send on a stream with a write direction, from now on every interval:
        held, or asked of a function each interval (values that follow the robot's `received`),
        which must give every writable node a value of its type and range."""
        stream = self._stream(path)
        codec = stream.codecs.get(Direction.WRITE)
        if codec is None:
            raise LocalProtocolError(f"{path} is set up with mode {stream.mode}: it writes nothing")
        if callable(values):
            self._writes[stream.id] = lambda: codec.encode(values())
        else:
            body = codec.encode(values)  # checked now, not at the first interval
            self._writes[stream.id] = lambda: body

    def _stream(self, path: str) -> Stream:
        stream_id = self.streams.get(path)
        if self.endpoint is None or stream_id is None or stream_id not in self.endpoint.streams:
            raise LocalProtocolError(f"{path} is not set up as a stream")
        return self.endpoint.streams[stream_id]

    def _bodies(self, due: tuple[int, ...]) -> dict[int, bytes]:
        """The body of each due stream (`write_values`); none before the first."""
        return {s: self._writes[s]() for s in due if s in self._writes}

    def next_event(self) -> ClientEvent | None:
        return self._events.popleft() if self._events else None

    # -- events ------------------------------------------------------------------------------

    def _process(self, now: float) -> None:
        while (event := self.conn.next_event()) is not None:
            if isinstance(event, ResponseReceived):
                self._answered(event.request, event.response, now)
            elif isinstance(event, RequestReceived):
                self._server_request(event.request, now)
            elif isinstance(event, KeepAliveDue) and self.conn.session is not None:
                self.send("CONNECT", self.site_path, now=now)  # D-RCTP-11: the refresh
            elif isinstance(event, RequestRejected):
                self._events.append(
                    ServerRequest(event.request.method, event.request.target, event.status)
                )
            elif isinstance(event, SessionEnded):
                if event.by is Role.SERVER:
                    self._events.append(ServerRequest("BYE", "*", 200, reason=event.reason))
                self._close(f"the session ended ({event.reason or 'BYE'})")
            elif isinstance(event, ProtocolFailure):
                self._close(
                    f"the server broke the protocol: {event.error.reason} [{event.error.rule}]"
                )
            elif isinstance(event, ConnectionClosed):
                self._close("the server closed the connection")
        endpoint = self.endpoint
        while endpoint is not None and (stream_event := endpoint.next_event()) is not None:
            if isinstance(stream_event, ValuesReceived):
                path = self._path_of(stream_event.stream)
                if path is not None:
                    self.received[path] = stream_event.values
                    self._events.append(StreamValues(path, stream_event.values, stream_event.sent))
            elif isinstance(stream_event, StreamTimedOut):
                path = self._path_of(stream_event.stream)
                if path is not None:
                    self._events.append(StreamLost(path))
            elif isinstance(stream_event, ClockUpdated):
                self._events.append(ClockEstimated(stream_event.estimate))

    def _close(self, reason: str) -> None:
        if not self.closed:
            self.closed = True
            self._events.append(Closed(reason))

    def _path_of(self, stream_id: int) -> str | None:
        return next((p for p, s in self.streams.items() if s == stream_id), None)

    def _answered(self, request: Request, response: Response, now: float) -> None:
        """What a 200 to SETUP, GO, PAUSE and STOP of a stream access changes on the data stream.

        A server under test may answer wrongly; what cannot be used is reported in `problem`,
        never raised.
        """
        problem = None
        change = _STREAM_CHANGES.get(request.method)
        access = self._stream_access(request)
        if response.status == 200 and change is not None and access is not None:
            problem = change(self, access, request, response, now)
        self._events.append(Answered(request, response, problem))

    def _stream_access(self, request: Request) -> AccessNode | None:
        node = self.model.node(parse_target(request.target).path) if self.model else None
        return node if isinstance(node, AccessNode) and node.type is AccessType.STREAM else None

    def _set_up(
        self, access: AccessNode, request: Request, response: Response, now: float
    ) -> str | None:
        try:
            asked = parse_transport(request.headers.get("Transport") or "udp")
            given = parse_transport(response.headers.get("Transport") or "")
        except ValueTextError as exc:
            return f"the answer's Transport: {exc} (R-RCTP-38)"
        if given.server_port is None or given.tag is None or given.stream is None:
            return "the answer's Transport lacks server_port, tag or stream (R-RCTP-38)"
        if self.endpoint is None:
            precision = self.model.time_precision if self.model is not None else None
            self.endpoint = Endpoint(
                Role.CLIENT,
                given.tag,
                first_sequence=self._first_sequence,
                unix_offset=self._unix_offset,
                precision=precision or 0.0,
                heartbeat_every=self._heartbeat_every,
            )
        elif given.tag != self.endpoint.tag:
            return f"the answer's tag {given.tag:08x} is not the session's (D-RCTP-28)"
        self.endpoint.peer = (self.server_host, given.server_port)
        self.endpoint.add_stream(given.stream, access, asked.mode)
        self.streams[access.path] = given.stream
        return None

    def _go(
        self, access: AccessNode, request: Request, response: Response, now: float
    ) -> str | None:
        if access.path not in self.streams or self.endpoint is None:
            return f"GO of {access.path} answered 200, but it is not set up"
        self.endpoint.play(self.streams[access.path], now)
        return None

    def _pause(
        self, access: AccessNode, request: Request, response: Response, now: float
    ) -> str | None:
        if access.path in self.streams and self.endpoint is not None:
            self.endpoint.pause(self.streams[access.path])
        return None

    def _stop(
        self, access: AccessNode, request: Request, response: Response, now: float
    ) -> str | None:
        self._forget(access.path)
        return None

    def _forget(self, path: str) -> None:
        stream_id = self.streams.pop(path, None)
        if stream_id is not None and self.endpoint is not None:
            self.endpoint.remove_stream(stream_id)
            self._writes.pop(stream_id, None)
            self.received.pop(path, None)

    # -- the server's requests ---------------------------------------------------------------

    def _server_request(self, request: Request, now: float) -> None:
        """R-RCTP-24: answer the server's WRITE and STOP (the core answers BYE itself)."""
        path = parse_target(request.target).path
        status, values = 200, None
        if request.method == "WRITE":
            try:
                values = self._decode_push(path, request)
            except (ProtocolError, ValueTextError, LocalProtocolError):
                status = 400
        elif request.method == "STOP":
            self._forget(path)
        self.conn.send_response(request, status)
        reason = request.headers.get("Reason")
        self._events.append(ServerRequest(request.method, path, status, values, reason))

    def _decode_push(self, path: str, request: Request) -> dict[str, Value]:
        """A data-change event's values (D-RCTP-27); bytes stay bytes without a model."""
        access = self.access(path)
        names = parse_nodes(request.headers.get("Nodes") or "")
        by_name = {node.name: node for node in access.data}
        if not set(names) <= by_name.keys():
            raise LocalProtocolError(f"Nodes names no data node of {path}")
        return ValuesCodec([by_name[n] for n in names], path, "R-RCTP-32").decode(request.body)


_Change = Callable[[ClientSession, AccessNode, Request, Response, float], "str | None"]
#: Method -> what its 200 changes on the data stream of a stream access.
_STREAM_CHANGES: dict[str, _Change] = {
    "SETUP": ClientSession._set_up,
    "GO": ClientSession._go,
    "PAUSE": ClientSession._pause,
    "STOP": ClientSession._stop,
}
