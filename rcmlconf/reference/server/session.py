"""One client of the reference server, without I/O: its control connection and its data stream.

The protocol core (`rctp.connection`) makes the first checks of D-RCTP-25 and answers them. What
reaches `_answer` is a request the robot must judge. Each method has a handler. The handler makes
the remaining checks in D-RCTP-25's order: the node (404, 405), the permission (403), the
privilege (470, 471), the transport (461), the body (411, 415, 422). It raises `Refused` at the
first check that fails. Otherwise it does what the request asks.

The server's own requests leave from here too: data-change WRITEs (D-RCTP-27), STOP of a stream
whose receive timeout passed (R-RCTP-45), and BYE.

The adapter feeds bytes, datagrams and timers in. It sends what `data_to_send` and
`datagrams_to_send` give. `finished` tells it to close the connection once everything is sent.
"""

from __future__ import annotations

import logging
from collections import deque
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass

from rcmlconf import __version__
from rcmlconf.errors import ProtocolError, ValueTextError
from rcmlconf.rcml.model import AccessNode, DataNode, Permission
from rcmlconf.rcml.paths import is_within
from rcmlconf.rctp.allowed import ALLOWED, TargetKind, target_kind
from rcmlconf.rctp.connection import (
    ConnectionClosed,
    ProtocolFailure,
    RequestReceived,
    RequestRejected,
    ResponseReceived,
    SessionEnded,
    SessionOpened,
    SessionTimedOut,
)
from rcmlconf.rctp.datastream.endpoint import MODE_DIRECTIONS, Address, Endpoint
from rcmlconf.rctp.datastream.events import StreamTimedOut, ValuesReceived
from rcmlconf.rctp.datastream.flow import Direction
from rcmlconf.rctp.fields import (
    Transport,
    format_nodes,
    parse_nodes,
    parse_transport,
    same_token,
)
from rcmlconf.rctp.messages import TEXT_TYPE, VALUES_TYPE, Request
from rcmlconf.rctp.states import Role, SessionState, StreamState
from rcmlconf.rctp.targets import STAR, Target, format_target
from rcmlconf.reference.ends import SessionEnd
from rcmlconf.reference.server.robot import Robot
from rcmlconf.values import Value
from rcmlconf.wording import shorten

log = logging.getLogger("rcmlconf.server")

PRODUCT = f"rcmlconf/{__version__}"
#: R-RCTP-55: the server's WRITE and STOP requests unanswered at once, at most.
MAX_UNANSWERED = 4
#: D-RCTP-18: stream ids are one byte, 0 being the session's.
MAX_STREAMS = 255

Answer = tuple[int, list[tuple[str, str]], bytes]


class Refused(Exception):
    """A check of D-RCTP-25 failed: the request is answered with this status."""

    def __init__(self, status: int, reason: str, rule: str, allow: Sequence[str] = ()) -> None:
        super().__init__(reason)
        self.status = status
        self.reason = reason
        self.rule = rule
        self.allow = tuple(allow)


@dataclass(slots=True)
class _StreamSetUp:
    access: AccessNode
    stream: int
    mode: str


class ServerSession(SessionEnd):
    def __init__(self, robot: Robot[ServerSession], peer: Address, now: float) -> None:
        super().__init__(Role.SERVER, now)
        self.robot = robot
        self.peer = peer
        self.id: str | None = None
        #: Stream accesses set up, by path; a stream keeps its id after STOP (D-RCTP-28).
        self._streams: dict[str, _StreamSetUp] = {}
        self._stream_ids: dict[str, int] = {}
        #: Event access path -> names of nodes changed since this session's last WRITE of it.
        self._changes: dict[str, set[str]] = {}
        #: Server STOPs waiting for room (R-RCTP-55).
        self._stops: deque[tuple[str, str]] = deque()
        #: The connection is over: close it once everything is sent.
        self.finished = False
        #: D-RCTP-32: when the connection opened, and when the request not yet whole began;
        #: since when the server holds the connection unread for its own reasons (not counted
        #: against the peer), and since when the peer takes nothing of what it is sent.
        self._opened = now
        self._partial_since: float | None = None
        self._held_since: float | None = None
        self._stalled_since: float | None = None
        #: The peer took nothing for the slow timeout: the connection is reset, not closed
        #: (what waits to be sent would never leave).
        self.reset = False

    def _bodies(self, due: tuple[int, ...]) -> dict[int, bytes]:
        """The robot's values, encoded once per tick for every session (`Robot.body`)."""
        assert self.endpoint is not None
        streams = self.endpoint.streams
        return {s: self.robot.body(streams[s].access, Direction.READ) for s in due}

    # -- slow connections (D-RCTP-32) ----------------------------------------------------------

    def receive_data(self, data: bytes, now: float) -> None:
        super().receive_data(data, now)
        # A request's first byte starts its clock; the request made whole stops it.
        if not self.conn.buffered:
            self._partial_since = None
        elif self._partial_since is None:
            self._partial_since = now

    def hold(self, now: float) -> None:
        """The server leaves the connection unread for its own reasons (D-RCTP-32: a large
        request waiting for a place): the time until `go_on` does not count against the peer."""
        if self._held_since is None:
            self._held_since = now

    def go_on(self, now: float) -> None:
        """The server reads the connection again: its slow clocks move on by the time held."""
        if self._held_since is None:
            return
        held = now - self._held_since
        self._held_since = None
        self._opened += held
        if self._partial_since is not None:
            self._partial_since += held

    def stalled(self, now: float | None) -> None:
        """The peer takes nothing of what the server sends since `now` (its answers piled up
        beyond what the server buffers, or left unsent when the server closes); None: it takes
        them again. The earliest such moment counts."""
        if now is None:
            self._stalled_since = None
        elif self._stalled_since is None:
            self._stalled_since = now

    def _slow_deadline(self) -> float | None:
        """When the connection is given up as too slow: no CONNECT taken by then, or the
        request under way not whole by then (neither while the server holds it unread); or
        its peer has taken nothing it was sent since the slow timeout, even once finished."""
        timeout = self.robot.limits.slow_timeout
        deadline = None if self._stalled_since is None else self._stalled_since + timeout
        if self.finished or self._held_since is not None:
            return deadline
        if self.id is None:
            opened = self._opened + timeout
            deadline = opened if deadline is None else min(deadline, opened)
        if self._partial_since is not None:
            partial = self._partial_since + timeout
            deadline = partial if deadline is None else min(deadline, partial)
        return deadline

    def maintenance_timer(self) -> float | None:
        if self.finished:
            return self._slow_deadline()
        timer = super().maintenance_timer()
        slow = self._slow_deadline()
        return slow if timer is None or (slow is not None and slow < timer) else timer

    def handle_timer(self, now: float) -> None:
        if not self.finished:
            super().handle_timer(now)
        slow = self._slow_deadline()
        if slow is None or now < slow:
            return
        timeout = self.robot.limits.slow_timeout
        if self._stalled_since is not None and now >= self._stalled_since + timeout:
            what = "its answers not taken"
            self.reset = True
        else:
            what = "no CONNECT" if self.id is None else "a request not whole"
        log.info("%s closed: %s within %g s (D-RCTP-32)", self._who(), what, timeout)
        self._end()

    def shut_down(self, now: float) -> None:
        """Graceful shutdown: BYE with `Reason: shutdown`; the session ends when it is answered
        or after 5 s (R-RCTP-23)."""
        if self.conn.session_state is SessionState.OPEN:
            self.conn.send_request("BYE", STAR, [("Reason", "shutdown")], now=now)
        else:
            self._end()

    # -- events ------------------------------------------------------------------------------

    def _process(self, now: float) -> None:
        while (event := self.conn.next_event()) is not None:
            if isinstance(event, RequestReceived):
                self._answer(event, now)
            elif isinstance(event, RequestRejected):
                self._log(event.request, event.status, event.reason)
            elif isinstance(event, ResponseReceived):
                self._answered(event, now)
            elif isinstance(event, SessionOpened):
                log.info("%s session opened", self._who())
            elif isinstance(event, SessionTimedOut):
                log.info("%s session timed out: BYE", self._who())
            elif isinstance(event, ProtocolFailure):
                log.info("%s %s [%s]", self._who(), event.error.reason, event.error.rule)
                self._protocol_failed()
            elif isinstance(event, SessionEnded | ConnectionClosed):
                self._end()
        endpoint = self.endpoint
        while endpoint is not None and (stream_event := endpoint.next_event()) is not None:
            if isinstance(stream_event, ValuesReceived):
                setup = self._stream_by_id(stream_event.stream)
                if setup is not None:
                    base = setup.access.path
                    values = {f"{base}/{name}": v for name, v in stream_event.values.items()}
                    self.robot.command(self, values, now)
            elif isinstance(stream_event, StreamTimedOut):
                self._stream_lost(stream_event.stream, now)
            else:
                log.debug("%s data stream: %s", self._who(), stream_event)
        self._pump(now)

    def _protocol_failed(self) -> None:
        """R-RCTP-8, R-RCTP-12: a message the server cannot frame or take ends the connection."""
        self._end()

    def _end(self) -> None:
        if not self.finished:
            self.finished = True
            tag = self.endpoint.tag if self.endpoint is not None else None
            self.robot.close_session(self, self.id, tag)
            log.info("%s session ended", self._who())

    def _who(self) -> str:
        return f"{self.peer[0]}:{self.peer[1]}"

    def _log(self, request: Request, status: int, reason: str = "") -> None:
        if log.isEnabledFor(logging.INFO):
            detail = f" ({shorten(reason, 80)})" if reason and status != 200 else ""
            log.info(
                "%s %s %s -> %d%s", self._who(), request.method, request.target, status, detail
            )

    # -- requests the robot judges -----------------------------------------------------------

    def _answer(self, event: RequestReceived, now: float) -> None:
        request = event.request
        handler: _Handler = getattr(self, _HANDLERS[request.method])
        try:
            status, headers, body = handler(request, event.target, now)
        except Refused as refusal:
            status, body = refusal.status, refusal.reason.encode("utf-8")
            headers = [("Content-Type", TEXT_TYPE)]
            if refusal.allow:
                headers.insert(0, ("Allow", ", ".join(refusal.allow)))
            self._log(request, status, f"{refusal.reason} [{refusal.rule}]")
        else:
            self._log(request, status)
        self.conn.send_response(request, status, headers, body)

    def _node_kind(self, request: Request, target: Target) -> TargetKind:
        """D-RCTP-26: 404 for no node, 405 (with `Allow`) for a method its kind does not take."""
        kind = target_kind(self.robot.model, target.path)
        if kind is None:
            raise Refused(404, f"no node {shorten(target.path, 80)}", "R-RCTP-26")
        if request.method not in ALLOWED[kind]:
            raise Refused(
                405, f"{request.method} does not apply to {kind.value}", "R-RCTP-26", ALLOWED[kind]
            )
        return kind

    def _access(self, target: Target) -> AccessNode:
        node = self.robot.model.node(target.path)
        assert isinstance(node, AccessNode)  # the node check said so
        return node

    def _session_id(self) -> str:
        assert self.id is not None  # the core passes nothing but CONNECT before the session
        return self.id

    def _connect(self, request: Request, target: Target, now: float) -> Answer:
        if target.path != self.robot.site_path:
            raise Refused(
                404,
                f"no robot at {shorten(target.path, 80)}; try {self.robot.site_path}",
                "R-RCTP-26",
            )
        if self.id is None:
            self.id = self.robot.open_session(self)
            if self.id is None:
                cap = self.robot.limits.sessions_per_peer
                raise Refused(503, f"{cap} sessions of {self.peer[0]} are open", "R-RCTP-67")
        session = f"{self.id};timeout={self.robot.session_timeout}"
        return 200, [("Session", session), ("Server", PRODUCT)], b""

    def _acquire(self, request: Request, target: Target, now: float) -> Answer:
        self._node_kind(request, target)
        if not self.robot.privileges.acquire(self._session_id(), target.path):
            held = f"another session holds {target.path}, a path above it or one below"
            raise Refused(471, held, "R-RCTP-33")
        return 200, [], b""

    def _release(self, request: Request, target: Target, now: float) -> Answer:
        writing = self._writing_below(target)
        if writing:  # R-RCTP-35: the stream would write without the privilege
            raise Refused(455, f"{writing[0]} is set up for writing: STOP it first", "R-RCTP-35")
        if target.is_session:
            self.robot.privileges.release_all(self._session_id())
            return 200, [], b""
        self._node_kind(request, target)
        if not self.robot.privileges.release(self._session_id(), target.path):
            raise Refused(470, f"this session did not acquire {target.path}", "R-RCTP-35")
        return 200, [], b""

    def _writing_below(self, target: Target) -> list[str]:
        """The stream accesses set up for writing at or below `target` (all of them for `*`)."""
        return [
            path
            for path, setup in self._streams.items()
            if Direction.WRITE in MODE_DIRECTIONS[setup.mode]
            and (target.is_session or is_within(path, target.path))
        ]

    def _read(self, request: Request, target: Target, now: float) -> Answer:
        kind = self._node_kind(request, target)
        nodes = self._nodes(request, target, kind, Permission.READ)
        body = self.robot.codec(target.path, nodes).encode(self.robot.values(nodes))
        headers = (
            [("Nodes", format_nodes([n.name for n in nodes]))]
            if kind is TargetKind.EVENT_ACCESS
            else []
        )
        return 200, headers, body

    def _write(self, request: Request, target: Target, now: float) -> Answer:
        kind = self._node_kind(request, target)
        nodes = self._nodes(request, target, kind, Permission.WRITE)
        for node in nodes:
            self._privileged(node.path)
        if "Content-Length" not in request.headers:
            raise Refused(411, "a WRITE carries its values, with Content-Length", "R-RCTP-6")
        if not self._same_token(request.headers.get("Content-Type"), VALUES_TYPE):
            raise Refused(415, f"a WRITE's body is {VALUES_TYPE}", "R-RCTP-6")
        try:
            values = self.robot.codec(target.path, nodes).decode(request.body)
        except ProtocolError as error:
            raise Refused(422, f"{error.reason} (body byte {error.offset})", "R-RCTP-28") from None
        self._apply(nodes, values, now)
        return 200, [], b""

    def _same_token(self, given: str | None, token: str) -> bool:
        """D-RCTP-30: a token of the grammar is read in any letter case."""
        return same_token(given, token)

    def _apply(self, nodes: Sequence[DataNode], values: Mapping[str, Value], now: float) -> None:
        """R-RCTP-28, R-RCTP-29: a WRITE's values are applied all together, or none is (422)."""
        for node in nodes:
            problem = self._out_of_range(node, values[node.name])
            if problem is not None:
                raise Refused(422, problem, "R-RCTP-28")
        self.robot.command(self, {node.path: values[node.name] for node in nodes}, now)

    def _out_of_range(self, node: DataNode, value: Value) -> str | None:
        """Why `value` is outside the node's range, or None (R-RCTP-28)."""
        return node.out_of_range(value)

    def _nodes(
        self, request: Request, target: Target, kind: TargetKind, needed: Permission
    ) -> tuple[DataNode, ...]:
        """The data nodes a READ or WRITE concerns (D-RCTP-17), each allowed `needed` (403)."""
        if kind is TargetKind.NORMAL_DATA:
            node = self.robot.model.node(target.path)
            assert isinstance(node, DataNode)
            nodes: tuple[DataNode, ...] = (node,)
        else:
            nodes = self._listed(request, self._access(target), needed)
        for node in nodes:
            self._permitted(node, needed)
        return nodes

    def _permitted(self, node: DataNode, needed: Permission) -> None:
        """R-RCTP-27: 403 for a node the request may not read or write."""
        if needed not in node.permission:
            verb = "read" if needed is Permission.READ else "written"
            raise Refused(
                403, f"{node.path} may not be {verb} ({node.permission.to_text()})", "R-RCTP-27"
            )

    def _listed(
        self, request: Request, access: AccessNode, needed: Permission
    ) -> tuple[DataNode, ...]:
        """`Nodes` of an event access (R-RCTP-30): required in a WRITE; all readable in a READ."""
        text = request.headers.get("Nodes")
        if text is None:
            if needed is Permission.WRITE:
                raise Refused(
                    400, "a WRITE of an event access lists its nodes in Nodes", "R-RCTP-30"
                )
            return access.readable()
        try:
            names = parse_nodes(text)
        except ValueTextError as exc:
            raise Refused(400, str(exc), "R-RCTP-30") from None
        by_name = {node.name: node for node in access.data}
        unknown = [name for name in names if name not in by_name]
        if unknown:
            raise Refused(
                400, f"{access.path} has no data node {shorten(unknown[0], 40)}", "R-RCTP-30"
            )
        return tuple(by_name[name] for name in names)

    def _privileged(self, path: str) -> None:
        """R-RCTP-34: writing needs the privilege of the path."""
        holder = self.robot.privileges.holder(path)
        if holder is None:
            raise Refused(470, f"ACQUIRE {path} (or a path above it) first", "R-RCTP-34")
        if holder != self.id:
            raise Refused(471, f"another session holds {path}", "R-RCTP-34")

    def _setup(self, request: Request, target: Target, now: float) -> Answer:
        kind = self._node_kind(request, target)
        access = self._access(target)
        if kind is TargetKind.EVENT_ACCESS:
            return 200, [], b""
        transport = self._transport(request, access)
        stream = self._stream_ids.get(access.path)
        if stream is None:
            if len(self._stream_ids) >= MAX_STREAMS:
                raise Refused(461, f"a session has at most {MAX_STREAMS} streams", "R-RCTP-38")
            stream = self._stream_ids[access.path] = len(self._stream_ids) + 1
        assert transport.client_port is not None
        endpoint = self._endpoint(now)
        self._stream_to(endpoint, transport.client_port)
        endpoint.add_stream(stream, access, transport.mode)
        self._streams[access.path] = _StreamSetUp(access, stream, transport.mode)
        answer = Transport(
            client_port=transport.client_port,
            mode=transport.mode,
            server_port=self.robot.data_port,
            tag=endpoint.tag,
            stream=stream,
        )
        return 200, [("Transport", str(answer))], b""

    def _stream_to(self, endpoint: Endpoint, client_port: int) -> None:
        """R-RCTP-56: the data stream goes to the client_port of the latest SETUP."""
        endpoint.peer = (self.peer[0], client_port)

    def _transport(self, request: Request, access: AccessNode) -> Transport:
        """D-RCTP-28: the permission and the privilege of the mode, then the transport itself."""
        text = request.headers.get("Transport")
        if text is None:
            raise Refused(461, "SETUP of a stream access names its Transport", "R-RCTP-57")
        try:
            transport = self._parse_transport(text)
        except ValueTextError as exc:
            raise Refused(400, str(exc), "R-RCTP-38") from None
        directions = MODE_DIRECTIONS[transport.mode]
        for direction in sorted(directions):
            nodes = access.readable() if direction is Direction.READ else access.writable()
            if not nodes:
                which = direction.name.lower()
                raise Refused(403, f"{access.path} has no node to {which}", "R-RCTP-57")
        if Direction.WRITE in directions:
            for node in access.writable():
                self._privileged(node.path)
        if transport.client_port is None:
            raise Refused(461, "the Transport names no client_port", "R-RCTP-57")
        if (transport.server_port, transport.tag, transport.stream) != (None, None, None):
            raise Refused(461, "the server chooses server_port, tag and stream", "R-RCTP-38")
        return transport

    def _parse_transport(self, text: str) -> Transport:
        """The Transport field, its tokens read in any letter case (D-RCTP-30)."""
        return parse_transport(text)

    def _endpoint(self, now: float) -> Endpoint:
        if self.endpoint is None:
            robot = self.robot
            tag = robot.new_tag(self)
            first_sequence = int.from_bytes(robot.random_bytes(2), "big")  # R-RCTP-41
            self.endpoint = self._new_endpoint(tag, first_sequence)
        return self.endpoint

    def _new_endpoint(self, tag: int, first_sequence: int) -> Endpoint:
        """The session's data stream (D-RCTP-18)."""
        unix_offset = self.robot.unix_offset
        return Endpoint(Role.SERVER, tag, first_sequence=first_sequence, unix_offset=unix_offset)

    def _go(self, request: Request, target: Target, now: float) -> Answer:
        kind = self._node_kind(request, target)
        if kind is TargetKind.EVENT_ACCESS:
            self.robot.watch(self, target.path)
            return 200, [], b""
        setup = self._streams[target.path]
        if Direction.WRITE in MODE_DIRECTIONS[setup.mode]:
            for node in setup.access.writable():
                self._privileged(node.path)
        assert self.endpoint is not None
        self.endpoint.play(setup.stream, now)
        return 200, [], b""

    def _pause(self, request: Request, target: Target, now: float) -> Answer:
        kind = self._node_kind(request, target)
        if kind is TargetKind.EVENT_ACCESS:
            self.robot.unwatch(self, target.path)
        else:
            self._pause_stream(target.path)
        return 200, [], b""

    def _pause_stream(self, path: str) -> None:
        """R-RCTP-44: a paused stream access sends no DATA."""
        assert self.endpoint is not None
        self.endpoint.pause(self._streams[path].stream)

    def _stop(self, request: Request, target: Target, now: float) -> Answer:
        kind = self._node_kind(request, target)
        if kind is TargetKind.EVENT_ACCESS:
            self.robot.unwatch(self, target.path)
            self._changes.pop(target.path, None)
        else:
            self._forget_stream(target.path)
        return 200, [], b""

    def _bye(self, request: Request, target: Target, now: float) -> Answer:
        self._node_kind(request, target)  # BYE of `*` is the core's; of a node, 404 or 405
        raise AssertionError("D-RCTP-26 allows BYE of * alone")

    def _forget_stream(self, path: str) -> None:
        setup = self._streams.pop(path, None)
        if setup is not None and self.endpoint is not None:
            self.endpoint.remove_stream(setup.stream)

    def _stream_by_id(self, stream: int) -> _StreamSetUp | None:
        return next((s for s in self._streams.values() if s.stream == stream), None)

    # -- the server's own requests -----------------------------------------------------------

    def note_changes(self, access: str, names: Iterable[str], now: float) -> None:
        """The robot: these nodes of a watched event access changed (D-RCTP-27)."""
        node = self.robot.model.node(access)
        assert isinstance(node, AccessNode)
        readable = {n.name for n in node.readable()}
        changed = readable.intersection(names)
        if changed:
            self._changes.setdefault(access, set()).update(changed)
            self._pump(now)

    def _stream_lost(self, stream: int, now: float) -> None:
        """R-RCTP-45: the client's writes stopped for the stream's timeout: STOP it."""
        setup = self._stream_by_id(stream)
        if setup is None or self.endpoint is None:
            return
        self.endpoint.pause(stream)
        self._stops.append((format_target(setup.access.path), "timeout"))
        log.info("%s %s: no DATA for its timeout: STOP", self._who(), setup.access.path)

    def _answered(self, event: ResponseReceived, now: float) -> None:
        request = event.request
        self._log(request, event.response.status)
        if request.method == "STOP":
            target = request.target
            path = next((p for p in self._streams if format_target(p) == target), None)
            if path is not None and event.response.status == 200:
                self._forget_stream(path)

    def _pump(self, now: float) -> None:
        """Send what waits while fewer than four WRITE and STOP requests are unanswered."""
        conn = self.conn
        if not (self._stops or self._changes) or conn.session_state is not SessionState.OPEN:
            return
        room = self._room()
        while room > 0 and (self._stops or self._changes):
            if self._stops:
                target, reason = self._stops.popleft()
                conn.send_request("STOP", target, [("Reason", reason)], now=now)
            else:
                access_path, names = next(iter(self._changes.items()))
                del self._changes[access_path]
                self._push(access_path, names, now)
            room -= 1

    def _room(self) -> int:
        """R-RCTP-55: how many more WRITE and STOP requests the server may have unanswered."""
        unanswered = self.conn.requests_unanswered
        return MAX_UNANSWERED - sum(1 for r in unanswered if r.method in ("WRITE", "STOP"))

    def _push(self, access_path: str, names: set[str], now: float) -> None:
        """A data-change event: WRITE of the access with the changed nodes' newest values."""
        if self.conn.streams.get(access_path) is not StreamState.PLAYING:
            return
        access = self.robot.model.node(access_path)
        assert isinstance(access, AccessNode)
        nodes = tuple(n for n in access.data if n.name in names)
        target = Target(access_path)
        body = self.robot.codec(target.path, nodes).encode(self.robot.values(nodes))
        headers = [("Nodes", format_nodes(sorted(names)))]
        self.conn.send_request("WRITE", format_target(access_path), headers, body, now=now)


_Handler = Callable[[Request, Target, float], Answer]
#: D-RCTP-12: the handler of each method a client may send, by its name on `ServerSession`.
#: A name, not the function, so that a subclass's handler is the one called.
_HANDLERS: dict[str, str] = {
    "CONNECT": "_connect",
    "ACQUIRE": "_acquire",
    "RELEASE": "_release",
    "READ": "_read",
    "WRITE": "_write",
    "SETUP": "_setup",
    "GO": "_go",
    "PAUSE": "_pause",
    "STOP": "_stop",
    "BYE": "_bye",
}
