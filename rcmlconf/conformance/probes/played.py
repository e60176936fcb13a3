"""The server the harness plays to an RCTP/2.0 client running D-RCTP-31's scenario: it answers
each request as a conforming server of the played robot would (D-RCTP-12 to D-RCTP-28) and keeps
everything the client did, for the client cases to judge.

It is deliberately lenient where the cases are strict: it answers what it can, so that a client
that breaks one rule still runs the rest of the scenario, and the case that checks the rule finds
the fault in `seen` (every request, when it came, what it was answered), `writes` (the values each
WRITE answered 200 set) and `refused_bodies` (WRITE bodies that did not decode). A case changes
the robot's values before the client reads them (`values`), or answers a request itself (`own`).
"""

from __future__ import annotations

import asyncio
import secrets
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

from rcmlconf.conformance.kept import Kept
from rcmlconf.conformance.probes.control import ControlProbe, waited_out
from rcmlconf.conformance.probes.datagrams import FIRST, LAST
from rcmlconf.conformance.probes.played_stream import PlayedStream
from rcmlconf.conformance.verdicts import Failed, Inconclusive
from rcmlconf.errors import ProtocolError, ValueTextError
from rcmlconf.rcml.model import AccessNode, AccessType, DataNode
from rcmlconf.rctp.bodies import ValuesCodec
from rcmlconf.rctp.fields import format_nodes, parse_nodes, parse_transport
from rcmlconf.rctp.messages import Request, Response
from rcmlconf.rctp.targets import format_target, parse_target
from rcmlconf.values import Value

if TYPE_CHECKING:
    from rcmlconf.conformance.context import Context

#: The session timeout the played server announces (D-RCTP-11's default).
SESSION_TIMEOUT = 60
#: D-RCTP-31's run takes about 5 s on the harness's robot (1 s of events, 2.25 s of stream).
SCENARIO_TIME = 15.0
Fields = list[tuple[str, str]]
#: A case's own answer to a request: the bytes to send (none: it is left unanswered), or None for
#: the played server's.
Own = Callable[[Request], bytes | None]


@dataclass(frozen=True, slots=True)
class Seen:
    """One request of the client's, as the played server got it."""

    request: Request
    #: The loop's time when it was answered (a held answer's, after the hold).
    at: float
    #: What it was answered (0: the case answered it itself).
    status: int

    @property
    def path(self) -> str | None:
        return path_of(self.request)

    def names(self, method: str, path: str | None = None) -> bool:
        """Whether it is a `method` request (of `path`, when given)."""
        return self.request.method == method and (path is None or self.path == path)


def path_of(request: Request) -> str | None:
    """A request's target's node path, percent-decoded; None when it is no target."""
    try:
        return parse_target(request.target).path
    except ValueTextError:
        return None


async def played(ctx: Context) -> PlayedServer:
    """The client under test's connection for the case, and the server played to it."""
    return PlayedServer(ctx, await ctx.client())


def shout(name: str, value: str) -> str:
    """A field's value with the tokens R-RCTP-59 compares without regard to case in another
    case: `Application/RCTP-Values`, `;TIMEOUT=60`, `UDP;CLIENT_PORT=...;MODE=BOTH`."""
    lower = name.lower()
    if lower == "content-type":
        return "Application/RCTP-Values" if value == "application/rctp-values" else value
    if lower == "session":
        return value.replace(";timeout=", ";TIMEOUT=")
    if lower != "transport":
        return value
    words = []
    for word in value.split(";"):
        key, equals, given = word.partition("=")
        words.append(key.upper() + equals + (given.upper() if key == "mode" else given))
    return ";".join(words)


@dataclass
class Write:
    """A WRITE of the client's the played server took: its target and the values it set."""

    path: str
    values: dict[str, Value]
    #: Its `Nodes`, as sent (an event access's), or None.
    nodes: str | None = None


class PlayedServer:
    def __init__(self, ctx: Context, probe: ControlProbe) -> None:
        self.ctx = ctx
        self.probe = probe
        self.robot = ctx.robot
        #: Every data node's value by path: what READ answers and WRITE changes.
        self.values: dict[str, Value] = {node.path: node.zero() for node in self.robot.data_nodes()}
        #: The client's requests, the WRITEs taken, and the WRITEs whose body did not decode or
        #: held a value out of range, with why: each its first and last (a client that sends more
        #: floods the harness).
        self.seen: Kept[Seen] = Kept(FIRST, LAST)
        self.writes: Kept[Write] = Kept(FIRST, LAST)
        self.refused_bodies: Kept[tuple[Request, str]] = Kept(FIRST, LAST)
        self.own: Own | None = None
        #: The data stream, once a stream access was set up.
        self.stream: PlayedStream | None = None
        #: Whether the answers spell the tokens R-RCTP-59 makes case-insensitive otherwise.
        self.shouting = False
        #: Seconds the answer to a request of a method waits: a slow server, within the 5 s a
        #: client waits (D-RCTP-31), opens a window in which to see what the client does early.
        self.holds: dict[str, float] = {}
        #: The session timeout CONNECT's answer gives (D-RCTP-11): a case makes it short to see
        #: the client refresh.
        self.session_timeout = SESSION_TIMEOUT
        self._playing: set[str] = set()
        self._set_up: set[str] = set()
        self.loop = asyncio.get_running_loop()

    # -- serving ---------------------------------------------------------------------------------

    async def serve(
        self, until: Callable[[Seen], bool] = lambda _: False, wait: float | None = None
    ) -> Seen | None:
        """Answer the client's requests until one `until` is true of (answered first: returned),
        the client closes the connection (None), or `wait` passes (the case's time left less a
        second by default; None)."""
        left = self.ctx.left - 1.0 if wait is None else wait
        deadline = self.loop.time() + left
        while (remaining := deadline - self.loop.time()) > 0:
            message = await self._next(remaining)
            if message is None:
                return None
            seen = await self._take(message)
            if until(seen):
                return seen
        return None

    async def reach(self, method: str, path: str | None = None) -> Seen | None:
        """Serve until the client's `method` request (of `path`), answered: `serve`'s `until`
        for the scenario's steps."""
        return await self.serve(until=lambda seen: seen.names(method, path))

    async def _next(self, wait: float) -> Request | None:
        """The client's next request within `wait`; None when it closes or none comes."""
        deadline = self.loop.time() + wait
        while (left := deadline - self.loop.time()) > 0:
            try:
                found = await self.probe.message(left)
            except Failed as failed:
                if failed.requirement != "R-RCTP-5":
                    raise
                if not self.seen and waited_out(failed):  # not even CONNECT: nothing to judge
                    raise Inconclusive(
                        f"the client connected and sent no request within {wait:.3g} s"
                        " (D-RCTP-31 step 2: it sends CONNECT)"
                    ) from None
                return None  # nothing came in time: the case judges what is missing
            if found is None or isinstance(found, Request):
                return found
            # A response to nothing the played server asked (a case that sent a request of its
            # own reads its answer itself): only noted.
            self.probe.transcript.note(f"{self.probe.name} (an answer to no request: ignored)")
        return None

    async def _take(self, request: Request) -> Seen:
        own = self.own(request) if self.own is not None else None
        if own is not None:
            if own:
                await self.probe.send(own)
            else:
                self.probe.transcript.note(f"{self.probe.name} (left unanswered)")
            seen = Seen(request, self.loop.time(), 0)
        else:
            if hold := self.holds.get(request.method):
                self.probe.transcript.note(f"(the answer to {request.method} waits {hold:g} s)")
                await asyncio.sleep(hold)
            status, reason, fields, body = await self._answer(request)
            if self.shouting:
                fields = [(name, shout(name, value)) for name, value in fields]
            await self.probe.send(self.probe.response_bytes(request, status, reason, fields, body))
            seen = Seen(request, self.loop.time(), status)
        self.seen.append(seen)
        return seen

    # -- answers ----------------------------------------------------------------------------------

    async def _answer(self, request: Request) -> tuple[int, str, Fields, bytes]:
        method = request.method
        if self.probe.session is None:
            if method != "CONNECT":
                return 454, "Session Not Found", [], b""
            self.probe.session = secrets.token_hex(8)
            session = f"{self.probe.session};timeout={self.session_timeout}"
            return 200, "OK", [("Session", session)], b""
        if request.headers.get("Session") != self.probe.session:
            return 454, "Session Not Found", [], b""
        try:
            path = parse_target(request.target).path
        except ValueTextError:
            return 400, "Bad Request", [], b""
        node = self.robot.node(path)
        try:
            if method in ("CONNECT", "ACQUIRE", "RELEASE", "BYE"):
                return 200, "OK", [], b""
            if method == "READ":
                return self._read(request, node)
            if method == "WRITE":
                return self._write(request, path, node)
            if method in ("SETUP", "GO", "PAUSE", "STOP"):
                return await self._stream_state(request, path, node)
        except _Refused as refused:
            return refused.status, refused.reason, [], b""
        return 501, "Not Implemented", [], b""

    def _read(self, request: Request, node: object) -> tuple[int, str, Fields, bytes]:
        nodes = self._nodes_of(request, node, "r")
        codec = ValuesCodec(nodes, "READ", "R-RCTP-28")
        body = codec.encode({n.name: self.values[n.path] for n in nodes})
        fields: Fields = [("Content-Type", "application/rctp-values")]
        if isinstance(node, AccessNode):
            fields.append(("Nodes", format_nodes([n.name for n in codec.nodes])))
        return 200, "OK", fields, body

    def _write(self, request: Request, path: str, node: object) -> tuple[int, str, Fields, bytes]:
        nodes = self._nodes_of(request, node, "w")
        codec = ValuesCodec(nodes, f"WRITE {path}", "R-RCTP-28")
        try:
            values = codec.decode(request.body)
        except ProtocolError as error:
            self.refused_bodies.append((request, f"{error.reason} at byte {error.offset}"))
            return 422, "Unprocessable Content", [], b""
        for one in codec.nodes:
            why = one.out_of_range(values[one.name])
            if why is not None:
                self.refused_bodies.append((request, why))
                return 422, "Unprocessable Content", [], b""
        for one in codec.nodes:
            self.values[one.path] = values[one.name]
        self.writes.append(Write(path, values, request.headers.get("Nodes")))
        return 200, "OK", [], b""

    def _nodes_of(self, request: Request, node: object, right: str) -> tuple[DataNode, ...]:
        """The data nodes a READ or WRITE concerns (D-RCTP-17)."""
        if isinstance(node, DataNode):
            access = self.robot.node(node.path.rsplit("/", 1)[0])
            if isinstance(access, AccessNode) and access.type is AccessType.NORMAL:
                return (node,)
            raise _Refused(405, "Method Not Allowed")
        if not isinstance(node, AccessNode) or node.type is not AccessType.EVENT:
            raise _Refused(404 if node is None else 405, "Not Found or Not Allowed")
        listed = request.headers.get("Nodes")
        allowed = node.readable() if right == "r" else node.writable()
        if listed is None:
            if right == "w":
                raise _Refused(400, "Bad Request")  # D-RCTP-17: a WRITE names its nodes
            return allowed
        try:
            names = parse_nodes(listed)
        except ValueTextError:
            raise _Refused(400, "Bad Request") from None
        by_name = {n.name: n for n in allowed}
        if any(name not in by_name for name in names):
            raise _Refused(400, "Bad Request")
        return tuple(by_name[name] for name in names)

    async def _stream_state(
        self, request: Request, path: str, node: object
    ) -> tuple[int, str, Fields, bytes]:
        if not isinstance(node, AccessNode) or node.type is AccessType.NORMAL:
            raise _Refused(405, "Method Not Allowed")
        method = request.method
        if method == "SETUP":
            self._set_up.add(path)
            if node.type is AccessType.STREAM:
                return 200, "OK", [("Transport", await self._transport(request, node))], b""
            return 200, "OK", [], b""
        if path not in self._set_up:
            raise _Refused(455, "Method Not Valid in This State")
        if method == "GO":
            self._playing.add(path)
        else:
            self._playing.discard(path)
            if method == "STOP":
                self._set_up.discard(path)
        if node.type is AccessType.STREAM and self.stream is not None:
            self.stream.playing = path in self._playing
        return 200, "OK", [], b""

    async def _transport(self, request: Request, access: AccessNode) -> str:
        """D-RCTP-18, D-RCTP-28: the data stream opened (once) and the answer's `Transport`."""
        try:
            asked = parse_transport(request.headers.get("Transport") or "")
        except ValueTextError:
            raise _Refused(461, "Unsupported Transport") from None
        if asked.client_port is None:
            raise _Refused(461, "Unsupported Transport")
        if self.stream is None:
            self.stream = await PlayedStream.open(self.ctx, self.probe, self.values)
        self.stream.set_up(access, asked)
        return str(self.stream.transport)

    def playing(self, path: str) -> bool:
        return path in self._playing

    # -- what the client did ------------------------------------------------------------------

    def requests(self, method: str | None = None) -> list[Seen]:
        return [s for s in self.seen if method is None or s.request.method == method]

    def read_paths(self) -> set[str]:
        """The targets of the client's READs the played server answered 200."""
        return {s.path for s in self.requests("READ") if s.status == 200 and s.path is not None}

    # -- the server's own requests ------------------------------------------------------------

    def push(self, access: AccessNode, names: Sequence[str], body: bytes) -> bytes:
        """A data-change WRITE of `access` (D-RCTP-27) listing `names` in their order (a case may
        break D-RCTP-17's canonical order), with `body`: its bytes, numbered, for the case to
        send when it chooses and then take its `answer`."""
        fields = [("Nodes", ", ".join(format_nodes([name]) for name in names))]
        return self.probe.request_bytes("WRITE", format_target(access.path), fields, body)

    async def answer(self) -> Response:
        """The client's answer to the played server's latest request; the client's requests
        that come first are served (D-RCTP-6)."""
        deadline = self.loop.time() + self.probe.wait
        while (left := deadline - self.loop.time()) > 0:
            found = await self.probe.message(left)
            if found is None:
                raise Failed("R-RCTP-24", "an answer", "the connection closed without one")
            if isinstance(found, Response):
                return found
            await self._take(found)
        raise Failed("R-RCTP-24", "an answer", f"none within {self.probe.wait:g} s")


class _Refused(Exception):
    def __init__(self, status: int, reason: str) -> None:
        super().__init__(reason)
        self.status = status
        self.reason = reason
