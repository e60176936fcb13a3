"""The RCTP/2.0 server: sessions over TCP, the data stream over UDP (specs/rctp-2.0.md)."""

from __future__ import annotations

import asyncio
import collections
import secrets
import struct
import sys
import time
from dataclasses import dataclass, field
from typing import Any
from urllib.parse import quote

import bugs
import datagram as dg
import wire
from body import Body
from rcml import Malformed, Node, Robot, decode_run

SESSION_TIMEOUT = 60
BYE_WAIT = 5.0
MAX_OUTSTANDING = 4
TICK = 0.01
FLOW_ANSWERS = 64
MAX_CONNECTIONS = 512
ALLOW = {
    "star": ("RELEASE", "BYE"),
    "container": ("ACQUIRE", "RELEASE"),
    "normal-data": ("ACQUIRE", "RELEASE", "READ", "WRITE"),
    "event": ("ACQUIRE", "RELEASE", "READ", "WRITE", "SETUP", "GO", "PAUSE", "STOP"),
    "stream": ("ACQUIRE", "RELEASE", "SETUP", "GO", "PAUSE", "STOP"),
    "inner-data": ("ACQUIRE", "RELEASE"),
}
VALUES = "application/rctp-values"
STREAM_METHODS = ("GO", "PAUSE", "STOP", "SETUP", "ACQUIRE", "RELEASE")  # stop-pending-crash


class Refuse(Exception):
    """An error response: status, a text for people, and extra header fields."""

    def __init__(self, status: int, why: str, headers: list[tuple[str, str]] | None = None):
        super().__init__(why)
        self.status, self.headers = status, headers or []


def covers(above: str, path: str) -> bool:
    """Whether path is above's node or below it."""
    return above == "/" or path == above or path.startswith(above + "/")


def quote_name(name: str) -> str:
    return quote(name, safe="-._~!$&'()*+;=:@")


@dataclass
class Stream:
    """One event or stream access a session has set up (D-RCTP-14)."""

    access: Node
    sid: int
    state: str = "init"  # init, ready, playing
    mode: str = "read"
    sending: bool = False
    read_us: int = 0
    write_us: int = 0
    read_timeout_us: int = 0
    write_timeout_us: int = 0
    next_send: float = 0.0
    last_rx: float = 0.0
    lost: bool = False  # its write timeout passed and the server sent STOP; a GO clears it
    snapshot: dict[str, bytes] = field(default_factory=dict)  # event: the values last told

    @property
    def is_event(self) -> bool:
        return self.access.atype == "event"

    def reads(self) -> bool:
        return self.mode in ("read", "both") and bool(self.access.data("r"))

    def writes(self) -> bool:
        return self.mode in ("write", "both") and bool(self.access.data("w"))


class Session:
    def __init__(self, conn: Connection, peer_ip: str, tag: int, timeout: int) -> None:
        self.id = secrets.token_hex(16)
        self.conn = conn
        self.peer_ip = peer_ip
        self.tag = tag
        self.state = "open"  # open, closing, closed
        self.timeout = timeout
        self.streams: dict[str, Stream] = {}
        self.by_id: dict[int, Stream] = {}
        self.acquired: set[str] = set()
        self.client_port: int | None = None
        self.seq_out = 0 if "seq-start-zero" in conn.faults else secrets.randbelow(65536)
        self.highest_in: int | None = None
        self.flow_answers: collections.OrderedDict[int, bytes] = collections.OrderedDict()
        self.last_seen = 0.0
        self.send_timer: asyncio.TimerHandle | None = None


class Connection:
    """One control connection: requests in both directions, answered in order (D-RCTP-6)."""

    def __init__(self, server: Server, reader: asyncio.StreamReader, writer: asyncio.StreamWriter):
        self.server = server
        self.faults = server.faults
        self.sr, self.writer = reader, writer
        # start-line-limit-counts-crlf: the 4,096 bytes are taken to include the CRLF
        crlf = "start-line-limit-counts-crlf" in self.faults
        self.reader = wire.Reader(wire.MAX_START_LINE - 2 if crlf else wire.MAX_START_LINE)
        peer = writer.get_extra_info("peername")
        self.peer = f"{peer[0]}:{peer[1]}" if peer else "?"
        self.peer_ip = peer[0] if peer else ""
        self.session: Session | None = None
        self.out_cseq = 0 if "server-cseq-from-zero" in self.faults else 1
        self.outstanding: collections.deque[tuple[str, int, str]] = collections.deque()
        self.pending_stops: list[str] = []
        self.closed = False
        self.linger = False
        self.close_timer: asyncio.TimerHandle | None = None

    # -- the connection's life --

    async def run(self) -> None:
        try:
            while not self.closed:
                self.reader.twin_lengths_ok = self._lax_repeats()
                try:
                    msg = self.reader.next()
                except wire.FrameError as exc:
                    if bugs.on("bare-lf-hang") and str(exc) == "a line ending in a bare LF":
                        self._bug_bare_lf()
                    if not exc.response:
                        self.respond(exc.status, exc.cseq, [], text=str(exc))
                        await self.writer.drain()
                        self.linger = True
                    break
                if msg is None:
                    data = await self.sr.read(65536)
                    if not data:
                        break
                    self.reader.feed(data)
                    continue
                if bugs.on("zero-padded-length"):
                    self._bug_zero_padded(msg)
                if msg.request:
                    self.on_request(msg)
                else:
                    self.on_response(msg)
                if "one-message-per-read" in self.faults:
                    self.reader.buf.clear()
                if self.closed:
                    break
                await self.writer.drain()
                if self.linger:
                    break
            if self.linger and not self.closed:
                await self._linger()
        except (ConnectionError, OSError):
            pass
        finally:
            self.close()

    def _lax_repeats(self) -> bool:
        """The bug repeated-field-acquired: for a session holding a privilege, repeated
        fields are not checked, and twin Content-Length values are framed as one."""
        return bugs.on("repeated-field-acquired") and bool(self.session and self.session.acquired)

    def _bug_bare_lf(self) -> None:
        """The bug bare-lf-hang: with a session open, the line scanner waits for the CR."""
        if self.session is not None and self.session.state == "open":
            bugs.hang()

    def _bug_zero_padded(self, msg: wire.Message) -> None:
        """The bug zero-padded-length: once a stream is set up, a request's body goes to the
        stream code's reader, which takes a leading zero for an octal prefix and fails."""
        text = msg.one("content-length") or ""
        sess = self.session
        set_up = sess is not None and any(st.state != "init" for st in sess.streams.values())
        if set_up and len(text) > 1 and text.startswith("0"):
            bugs.crash(ValueError(f"invalid literal for int() with base 0: {text!r}"))

    def _bug_stop_pending(self, msg: wire.Message) -> None:
        """The bug stop-pending-crash: a request naming a stream whose timeout STOP is still
        unanswered goes to the stream's answer slot, which the STOP in flight holds, and fails."""
        sess = self.session
        if msg.method not in STREAM_METHODS or sess is None or sess.state != "open":
            return
        path = wire.parse_target(msg.target)
        for method, cseq, target in self.outstanding:
            if method == "STOP" and target == path:
                bugs.crash(KeyError(f"{path}: slot taken by the unanswered STOP (CSeq {cseq})"))

    async def _linger(self) -> None:
        """Half-close, then read and drop until the peer closes (at most BYE_WAIT seconds)."""
        try:
            if self.writer.can_write_eof():
                self.writer.write_eof()
            deadline = asyncio.get_running_loop().time() + BYE_WAIT
            while True:
                left = deadline - asyncio.get_running_loop().time()
                if left <= 0 or not await asyncio.wait_for(self.sr.read(65536), left):
                    break
        except (TimeoutError, ConnectionError, OSError):
            pass

    def close(self) -> None:
        if self.closed:
            return
        self.closed = True
        if self.close_timer:
            self.close_timer.cancel()
        if self.session is not None:
            self.server.end_session(
                self.session, released="keep-privilege-on-close" not in self.faults
            )
        self.writer.close()
        self.server.connections.discard(self)

    def log(self, text: str) -> None:
        if self.server.verbose:
            print(f"{time.strftime('%H:%M:%S')} {self.peer} {text}", file=sys.stderr)

    # -- sending --

    def respond(
        self,
        status: int,
        cseq: int | None,
        headers: list[tuple[str, str]],
        body: bytes = b"",
        text: str = "",
    ) -> None:
        fields: list[tuple[str, str]] = []
        if cseq is not None:
            fields.append(("CSeq", str(cseq)))
        if (
            self.session is not None
            and status != 454
            and not any(k == "Session" for k, _ in headers)
        ):
            fields.append(("Session", self.session.id))
        fields += headers
        ctype = VALUES
        if status >= 400 and text:
            body, ctype = text.encode("utf-8"), "text/plain; charset=utf-8"
        self.writer.write(
            wire.build(f"RCTP/2.0 {status} {wire.REASONS[status]}", fields, body, ctype)
        )

    def send_request(
        self, method: str, target: str, headers: list[tuple[str, str]], body: bytes = b""
    ) -> None:
        assert self.session is not None
        cseq = self.out_cseq
        self.out_cseq += 1
        self.outstanding.append((method, cseq, target))
        fields = [("CSeq", str(cseq)), ("Session", self.session.id), *headers]
        self.writer.write(wire.build(f"{method} {target} RCTP/2.0", fields, body, VALUES))
        self.log(f"server {method} {target}")

    def room(self) -> bool:
        return "unbounded-server-requests" in self.faults or len(self.outstanding) < MAX_OUTSTANDING

    def server_bye(self, reason: str) -> None:
        sess = self.session
        if sess is None or sess.state != "open" or self.closed:
            return
        self.send_request("BYE", "*", [("Reason", reason)])
        self.server.end_session(sess, released=True)
        sess.state = "closing"
        self.close_timer = asyncio.get_running_loop().call_later(BYE_WAIT, self.close)

    def server_stop(self, st: Stream) -> None:
        """D-RCTP-23: the write direction fell silent; the STOP goes out when there is room.
        The stream stays in its state until the STOP is answered 200 (D-RCTP-14)."""
        st.sending, st.lost = False, True
        if "stop-init-at-sending" in self.faults:
            st.state = "init"
        self.server.reschedule(self.session)
        self.pending_stops.append(st.access.path)
        self.flush()

    def flush(self) -> None:
        while self.pending_stops and self.room() and self.session and self.session.state == "open":
            self.send_request("STOP", self.pending_stops.pop(0), [("Reason", "timeout")])

    def push_changes(self, st: Stream) -> None:
        """D-RCTP-27: one WRITE per look, of every readable node changed since the last told."""
        if not self.room():
            return
        body = self.server.body
        changed = []
        for node in st.access.data("r"):
            now = node.encode(body.get(node.path))
            if st.snapshot.get(node.path) != now:
                changed.append((node, now))
        if not changed:
            return
        for node, now in changed:
            st.snapshot[node.path] = now
        names = ", ".join(quote_name(n.name) for n, _ in changed)
        target = quote_path(st.access.path)
        self.send_request("WRITE", target, [("Nodes", names)], b"".join(v for _, v in changed))

    # -- receiving --

    def on_response(self, msg: wire.Message) -> None:
        cseqs = msg.all("cseq")
        if (
            not self.outstanding
            or len(cseqs) != 1
            or wire.parse_cseq(cseqs[0]) != self.outstanding[0][1]
        ):
            self.log("a response that answers no outstanding request: closing")
            self.close()
            return
        method, _, target = self.outstanding.popleft()
        if method == "BYE":
            self.close()
            return
        if method == "STOP" and msg.status == 200 and self.session is not None:
            stopped = self.session.streams.get(target)
            if stopped is not None:
                stopped.state = "init"
        self.flush()

    def on_request(self, msg: wire.Message) -> None:
        if bugs.on("stop-pending-crash"):
            self._bug_stop_pending(msg)
        cseqs = msg.all("cseq")
        cseq = wire.parse_cseq(cseqs[0]) if len(cseqs) == 1 else None
        if self.session is not None and self.session.state == "open":
            self.session.last_seen = asyncio.get_running_loop().time()
        try:
            headers, body = self.dispatch(msg, cseq)
            status, text = 200, ""
        except Refuse as exc:
            status, text, headers, body = exc.status, str(exc), exc.headers, b""
        except Exception as exc:  # a bug of this server must not end the others' sessions
            print(f"{msg.method} {msg.target[:80]}: {exc!r}", file=sys.stderr)
            status, text, headers, body = 500, "internal error", [], b""
        self.respond(status, cseq, headers, body, text)
        self.log(f"{msg.method} {msg.target} -> {status}{' ' + text if text else ''}")
        if msg.method == "BYE" and status == 200:
            self.linger = True
        if status == 501 and "unknown-method-close" in self.faults:
            self.linger = True

    def dispatch(self, m: wire.Message, cseq: int | None) -> tuple[list[tuple[str, str]], bytes]:
        """The checks of D-RCTP-25, in its order; raises Refuse for the first that fails."""
        if m.method not in wire.METHODS:
            raise Refuse(
                400 if "unknown-method-close" in self.faults else 501, f"unknown method {m.method}"
            )
        if m.version != wire.VERSION:
            raise Refuse(505, f"version {m.version} is not supported")
        if cseq is None:
            raise Refuse(400, "a missing or unreadable CSeq")
        lax = self._lax_repeats()
        for name in wire.ONCE:
            if lax and name != "cseq":
                continue
            if len(m.all(name)) > 1:
                raise Refuse(400, f"{name} appears more than once")
        target = wire.parse_target(m.target)
        if target is None:
            raise Refuse(400, f"bad request-target {m.target[:80]}")
        sess = self.session
        field_ = m.one("session")
        sid = wire.parse_session(field_) if field_ is not None else None
        if m.method == "CONNECT":
            if field_ is not None and not self.same_session(sid):
                raise Refuse(454, "unknown session")
        elif not self.same_session(sid):
            raise Refuse(454, "no session" if sess is None else "not this connection's session")
        if sess is not None:
            if sess.state != "open":
                raise Refuse(455, "the session is closing")
            if m.method == "CONNECT" and field_ is None:
                raise Refuse(455, "one connection, one session")
            if "state-after-node" not in self.faults:
                self.check_state(sess, m.method, target)
        if m.method == "CONNECT":
            return self.connect(target)
        assert sess is not None
        kind, node = self.server.resolve(target)
        if m.method not in ALLOW[kind]:
            allow = [] if "no-allow-field" in self.faults else [("Allow", ", ".join(ALLOW[kind]))]
            raise Refuse(405, f"{m.method} does not apply to {target}", allow)
        if "state-after-node" in self.faults:
            self.check_state(sess, m.method, target)
        handler = getattr(self, "do_" + m.method.lower())
        result: tuple[list[tuple[str, str]], bytes] = handler(sess, m, target, node)
        return result

    def same_session(self, sid: str | None) -> bool:
        """Whether a Session field names this connection's session; IDs are compared
        exactly (D-RCTP-30), unless the fault session-id-any-case."""
        sess = self.session
        if sid is None or sess is None:
            return False
        if "session-id-any-case" in self.faults:
            return wire.ascii_lower(sid) == wire.ascii_lower(sess.id)
        return sid == sess.id

    def check_state(self, sess: Session, method: str, target: str) -> None:
        st = sess.streams.get(target)
        if method in ("GO", "PAUSE", "STOP") and (st is None or st.state == "init"):
            raise Refuse(455, f"{target} is not set up")
        if method == "SETUP" and st is not None and st.state == "playing":
            raise Refuse(455, f"{target} is playing")
        if method == "RELEASE" and "release-under-write-stream" not in self.faults:
            for other in sess.streams.values():
                path = other.access.path
                overlaps = target == "*" or covers(target, path) or covers(path, target)
                if overlaps and not other.is_event and other.state != "init" and other.writes():
                    raise Refuse(455, f"a writing stream is set up at {path}: STOP it first")

    # -- the methods --

    def connect(self, target: str) -> tuple[list[tuple[str, str]], bytes]:
        if target != self.server.site_path:
            raise Refuse(404, f"no robot at {target}")
        sess = self.session
        if sess is None:
            sess = self.session = self.server.new_session(self)
        sess.last_seen = asyncio.get_running_loop().time()
        return [("Session", f"{sess.id};timeout={sess.timeout}")], b""

    def do_acquire(self, sess: Session, m: wire.Message, target: str, node: Node | None) -> Any:
        for other in self.server.sessions:
            if other is sess:
                continue
            for path in other.acquired:
                below = covers(target, path)
                above = covers(path, target) and "acquire-ignores-ancestor" not in self.faults
                if below or above:
                    raise Refuse(471, f"another session holds {path}")
        if not self.server.holds(sess, target):
            # D-RCTP-16: a path above held ones takes them in; only the new path is held
            if "acquire-above-keeps-below" not in self.faults:
                sess.acquired = {p for p in sess.acquired if not covers(target, p)}
            sess.acquired.add(target)
        return [], b""

    def do_release(self, sess: Session, m: wire.Message, target: str, node: Node | None) -> Any:
        if target == "*":
            sess.acquired.clear()
        elif target in sess.acquired:
            sess.acquired.discard(target)
        else:
            raise Refuse(470, f"{target} was not acquired by this session")
        return [], b""

    def event_nodes(self, m: wire.Message, access: Node, right: str, required: bool) -> list[Node]:
        """The data nodes a Nodes field lists (R-RCTP-30), or all of the access with right."""
        text = m.one("nodes")
        if text is None:
            if required:
                raise Refuse(400, "a WRITE of an event access needs Nodes")
            nodes = access.data(right)
            if not nodes:
                raise Refuse(403, f"{access.path} has no node with permission {right}")
            return nodes
        nodes = []
        for item in text.split(","):
            name = wire.decode_name(item.strip(" \t"))
            child = access.children.get(name) if name is not None else None
            if child is None:
                raise Refuse(400, f"Nodes: {item.strip()!r} is not a data node of {access.path}")
            ordered = not nodes or child.name.encode() > nodes[-1].name.encode()
            if not ordered and "nodes-order-unchecked" not in self.faults:
                raise Refuse(400, "Nodes must list each node once, in canonical order")
            nodes.append(child)
        for child in nodes:
            if right not in child.perm:
                raise Refuse(403, f"{child.path} has no permission {right}")
        return nodes

    def do_read(self, sess: Session, m: wire.Message, target: str, node: Node | None) -> Any:
        assert node is not None
        body = self.server.body
        little = "int16-little-endian" in self.faults
        if node.kind == "data":
            if "r" not in node.perm:
                raise Refuse(403, f"{target} cannot be read")
            return [], node.encode(body.get(node.path), little)
        nodes = self.event_nodes(m, node, "r", required=False)
        names = ", ".join(quote_name(n.name) for n in nodes)
        return [("Nodes", names)], b"".join(n.encode(body.get(n.path), little) for n in nodes)

    def do_write(self, sess: Session, m: wire.Message, target: str, node: Node | None) -> Any:
        assert node is not None
        if node.kind == "data":
            if "w" not in node.perm:
                raise Refuse(403, f"{target} cannot be written")
            nodes = [node]
        else:
            nodes = self.event_nodes(m, node, "w", required=True)
        self.server.need_privilege(sess, [n.path for n in nodes])
        if not m.has_length:
            raise Refuse(411, "a WRITE needs Content-Length")
        ctype = m.one("content-type")
        if (m.body or ctype is not None) and (ctype is None or wire.ascii_lower(ctype) != VALUES):
            raise Refuse(415, f"the body is not {VALUES}")
        check_range = node.kind != "data" or "range-unchecked-normal" not in self.faults
        try:
            values = decode_run(nodes, m.body, self.faults, check_range)
        except Malformed as exc:
            if "event-write-partial" in self.faults and node.kind == "access":
                self._apply_prefix(nodes, m.body)
            raise Refuse(422, str(exc)) from exc
        for n, v in zip(nodes, values, strict=True):
            self.server.body.put(n, v)
        st = sess.streams.get(node.path if node.kind == "access" else "")
        if st is not None and "echo-own-write" not in self.faults:
            for n, v in zip(nodes, values, strict=True):
                if "r" in n.perm and n.path in st.snapshot:
                    st.snapshot[n.path] = n.encode(v)
        return [], b""

    def _apply_prefix(self, nodes: list[Node], body: bytes) -> None:
        """The fault event-write-partial: the values before the bad one are applied."""
        pos = 0
        for n in nodes:
            try:
                value, pos = n.decode(body, pos, self.faults)
            except Malformed:
                return
            if not n.in_range(value):
                return
            self.server.body.put(n, value)

    def do_setup(self, sess: Session, m: wire.Message, target: str, node: Node | None) -> Any:
        assert node is not None
        if node.atype == "event":
            st = self.server.stream_for(sess, node)
            st.state = "ready" if st.state == "init" else st.state
            return [], b""
        text = m.one("transport")
        params = wire.parse_transport(text) if text is not None else None
        mode = params.get("mode", "read") if params is not None else None
        if mode is not None:
            if mode in ("read", "both") and not node.data("r"):
                raise Refuse(403, f"{target} has no readable node")
            if mode in ("write", "both") and not node.data("w"):
                raise Refuse(403, f"{target} has no writable node")
            if mode in ("write", "both"):
                self.server.need_privilege(sess, [n.path for n in node.data("w")])
        if params is None:
            raise Refuse(461, "a SETUP of a stream needs Transport: udp;client_port=P")
        if "client_port" not in params and "setup-missing-client-port-ok" not in self.faults:
            raise Refuse(461, "Transport has no client_port")
        assert mode is not None
        if len(sess.by_id) >= 255 and node.path not in sess.streams:
            raise Refuse(461, "no stream id left in this session")
        st = self.server.stream_for(sess, node)
        st.mode = mode
        if st.state == "init":
            st.state = "ready"
        port = sess.client_port or 0
        if "client_port" in params:
            port = int(params["client_port"])
            # client-port-first-setup-only: a repeated SETUP's new port is answered, not used
            if sess.client_port is None or "client-port-first-setup-only" not in self.faults:
                sess.client_port = port
        tp = (
            f"udp;client_port={port};server_port={self.server.udp_port};tag={sess.tag:08x}"
            f";mode={mode};stream={st.sid}"
        )
        return [("Transport", tp)], b""

    def do_go(self, sess: Session, m: wire.Message, target: str, node: Node | None) -> Any:
        st = sess.streams[target]
        if not st.is_event and st.writes():
            self.server.need_privilege(sess, [n.path for n in st.access.data("w")])
        now = asyncio.get_running_loop().time()
        if not st.sending:
            st.next_send = now
            st.last_rx = now
            if st.is_event:
                body = self.server.body
                st.snapshot = {n.path: n.encode(body.get(n.path)) for n in st.access.data("r")}
        st.state, st.sending, st.lost = "playing", True, False
        self.server.reschedule(sess)
        return [], b""

    def do_pause(self, sess: Session, m: wire.Message, target: str, node: Node | None) -> Any:
        st = sess.streams[target]
        st.state = "ready"
        if "send-while-paused" not in self.faults or st.is_event:
            st.sending = False
        self.server.reschedule(sess)
        return [], b""

    def do_stop(self, sess: Session, m: wire.Message, target: str, node: Node | None) -> Any:
        st = sess.streams[target]
        st.state, st.sending = "init", False
        self.server.reschedule(sess)
        return [], b""

    def do_bye(self, sess: Session, m: wire.Message, target: str, node: Node | None) -> Any:
        self.server.end_session(sess, released=True)
        sess.state = "closed"
        return [], b""


def quote_path(path: str) -> str:
    return path if path == "/" else "/" + "/".join(quote_name(s) for s in path[1:].split("/"))


class _Udp(asyncio.DatagramProtocol):
    def __init__(self, server: Server) -> None:
        self.server = server

    def datagram_received(self, data: bytes, addr: tuple[str | Any, int]) -> None:
        try:
            self.server.on_datagram(data, addr)
        except Exception as exc:  # a bad packet must never stop the server
            print(f"data stream: {exc!r}", file=sys.stderr)

    def error_received(self, exc: Exception) -> None:
        pass  # an ICMP port unreachable from a client that went away


class Server:
    def __init__(
        self,
        robot: Robot,
        faults: set[str],
        verbose: bool = False,
        session_timeout: int = SESSION_TIMEOUT,
    ) -> None:
        self.robot = robot
        self.session_timeout = session_timeout
        self.faults = faults
        self.verbose = verbose
        self.site_path = wire.parse_target(robot.site_path) or robot.site_path  # percent-decoded
        self.sessions: set[Session] = set()
        self.tags: dict[int, Session] = {}
        self.connections: set[Connection] = set()
        self.udp: asyncio.DatagramTransport | None = None
        self.udp_port = 0
        self.body = Body(robot, time.monotonic())
        self._ticker: asyncio.Task[None] | None = None

    # -- tree and privilege --

    def resolve(self, target: str) -> tuple[str, Node | None]:
        if target == "*":
            return "star", None
        node = self.robot.nodes.get(target)
        if node is None:
            raise Refuse(404, f"no node {target}")
        if node.kind in ("root", "group") or (node.kind == "access" and node.atype == "normal"):
            return "container", node
        if node.kind == "access":
            return node.atype, node
        assert node.parent is not None
        return ("normal-data" if node.parent.atype == "normal" else "inner-data"), node

    def holds(self, sess: Session, path: str) -> bool:
        return any(covers(p, path) for p in sess.acquired)

    def need_privilege(self, sess: Session, paths: list[str]) -> None:
        """R-RCTP-34: 470 unless the session holds every path, 471 when another session does."""
        missing = [p for p in paths if not self.holds(sess, p)]
        if not missing:
            return
        for other in self.sessions:
            if other is not sess and any(
                covers(a, p) or covers(p, a) for a in other.acquired for p in missing
            ):
                raise Refuse(471, "another session holds it")
        raise Refuse(470, f"{missing[0]} is not acquired by this session")

    # -- sessions --

    def new_session(self, conn: Connection) -> Session:
        tag = secrets.randbits(32)
        while tag in self.tags:
            tag = secrets.randbits(32)
        sess = Session(conn, conn.peer_ip, tag, self.session_timeout)
        self.sessions.add(sess)
        self.tags[tag] = sess
        return sess

    def end_session(self, sess: Session, released: bool) -> None:
        if sess.state == "open" or sess in self.sessions:
            if released:
                sess.acquired.clear()
                self.sessions.discard(sess)
            for st in sess.streams.values():
                st.state, st.sending = "init", False
            if sess.send_timer:
                sess.send_timer.cancel()
            self.tags.pop(sess.tag, None)
        sess.state = "closed" if sess.state == "open" else sess.state

    def stream_for(self, sess: Session, access: Node) -> Stream:
        st = sess.streams.get(access.path)
        if st is not None:
            return st
        sid = 0
        if access.atype == "stream":
            sid = len(sess.by_id) + 1
        st = Stream(access, sid)
        if access.atype == "stream":
            st.read_us = dg.micros(access.read_interval or 0)
            st.write_us = dg.micros(access.write_interval or 0)
            st.read_timeout_us = dg.micros(access.read_timeout)
            st.write_timeout_us = dg.micros(access.write_timeout)
            sess.by_id[sid] = st
        sess.streams[access.path] = st
        return st

    # -- the clock of the server --

    async def ticker(self) -> None:
        loop = asyncio.get_running_loop()
        while True:
            await asyncio.sleep(TICK)
            try:
                self.tick(loop.time())
            except Exception as exc:  # keep serving the other sessions
                print(f"tick: {exc!r}", file=sys.stderr)

    def tick(self, now: float) -> None:
        self.body.step(time.monotonic())
        for sess in list(self.sessions):
            conn = sess.conn
            if sess.state != "open" or conn.closed:
                continue
            if now - sess.last_seen > sess.timeout and "no-session-timeout" not in self.faults:
                conn.server_bye("timeout")
                continue
            for st in list(sess.streams.values()):
                if st.state != "playing":
                    continue
                if st.is_event:
                    conn.push_changes(st)
                elif st.writes() and not st.lost and "no-write-timeout" not in self.faults:
                    silent = now - st.last_rx > st.write_timeout_us / 1e6
                    if silent:
                        conn.server_stop(st)
            conn.flush()

    # -- the data stream --

    def reschedule(self, sess: Session | None) -> None:
        if sess is None:
            return
        if sess.send_timer:
            sess.send_timer.cancel()
            sess.send_timer = None
        due = [st for st in sess.streams.values() if st.sending and not st.is_event and st.reads()]
        if not due or sess.client_port is None or sess.state != "open":
            return
        loop = asyncio.get_running_loop()
        when = max(min(st.next_send for st in due), loop.time())
        sess.send_timer = loop.call_at(when, self.send_due, sess)

    def send_due(self, sess: Session) -> None:
        sess.send_timer = None
        now = asyncio.get_running_loop().time()
        payloads = []
        for st in sess.streams.values():
            if not (st.sending and not st.is_event and st.reads()) or st.next_send > now + 0.0005:
                continue
            values = b"".join(
                n.encode(self.body.get(n.path), "int16-little-endian" in self.faults)
                for n in st.access.data("r")
            )
            payloads.append((dg.DATA, st.sid, values))
            st.next_send += st.read_us / 1e6
            if st.next_send < now:
                st.next_send = now + st.read_us / 1e6
        batch: list[tuple[int, int, bytes]] = []
        for p in payloads:
            if batch and 16 + sum(4 + len(b[2]) for b in batch) + 4 + len(p[2]) > dg.MAX_DATAGRAM:
                self.send_packet(sess, batch)
                batch = []
            batch.append(p)
        if batch:
            self.send_packet(sess, batch)
        self.reschedule(sess)

    def send_packet(self, sess: Session, payloads: list[tuple[int, int, bytes]]) -> None:
        if self.udp is None or sess.client_port is None:
            return
        packet = dg.build(sess.seq_out, sess.tag, payloads)
        sess.seq_out = (sess.seq_out + 1) % 65536
        self.udp.sendto(packet, (sess.peer_ip, sess.client_port))

    def on_datagram(self, data: bytes, addr: tuple[Any, int]) -> None:
        arrival = dg.ntp_now()
        parsed = dg.parse(data)
        if parsed is None:
            return
        seq, tag, payloads = parsed
        sess = self.tags.get(tag)
        if sess is None or sess.state != "open" or sess.client_port is None:
            return
        if "no-source-check" not in self.faults and (
            addr[0] != sess.peer_ip or addr[1] != sess.client_port
        ):
            return
        if "unknown-payload-drops-packet" in self.faults and any(
            ptype not in (dg.DATA, dg.FLOW) for ptype, _, _ in payloads
        ):
            return
        now = asyncio.get_running_loop().time()
        sess.last_seen = now
        window = 0 if "seq-accepts-duplicate" in self.faults else 1
        newer = dg.is_newer(seq, sess.highest_in, window)
        if newer:
            sess.highest_in = seq
        for ptype, sid, body in payloads:
            if ptype == dg.DATA and newer:
                self.on_data(sess, sid, body, now)
            elif ptype == dg.FLOW:
                self.on_flow(sess, sid, body, arrival)

    def on_data(self, sess: Session, sid: int, body: bytes, now: float) -> None:
        st = sess.by_id.get(sid)
        if bugs.on("bad-data-leak") and st is not None and st.state == "playing":
            writable = st.access.data("w") if st.writes() else []
            try:
                decode_run(writable, body, check_range=False)
            except Malformed:
                bugs.leak(body)  # the bug: a copy kept "for the log", never freed
        if st is None or st.state != "playing" or not st.writes():
            return
        nodes = st.access.data("w")
        try:
            values = decode_run(nodes, body, self.faults)
        except Malformed:
            return
        for n, v in zip(nodes, values, strict=True):
            self.body.put(n, v)
        st.last_rx = now

    def on_flow(self, sess: Session, sid: int, body: bytes, arrival: int) -> None:
        if len(body) < 4:
            return
        message, op, rid = struct.unpack_from("!BBH", body)
        if message != dg.REQUEST:
            return  # this server sends no FLOW request: an ACK or NACK answers nothing
        answer = sess.flow_answers.get(rid)
        if answer is None or "flow-no-dedupe" in self.faults:
            answer = self.flow_answer(sess, sid, op, rid, body, arrival)
            sess.flow_answers[rid] = answer
            sess.flow_answers.move_to_end(rid)
            while len(sess.flow_answers) > FLOW_ANSWERS:
                sess.flow_answers.popitem(last=False)
        self.send_packet(sess, [(dg.FLOW, sid, answer)])

    def flow_answer(
        self, sess: Session, sid: int, op: int, rid: int, body: bytes, arrival: int
    ) -> bytes:
        if not dg.HEARTBEAT <= op <= dg.SET_TIMEOUT:
            return dg.flow_nack(op, rid, dg.NACK_UNKNOWN_OP)
        size = {
            dg.HEARTBEAT: 12,
            dg.GET_INTERVAL: 5,
            dg.SET_INTERVAL: 9,
            dg.GET_TIMEOUT: 5,
            dg.SET_TIMEOUT: 9,
        }[op]
        if len(body) != size or (op != dg.HEARTBEAT and body[4] not in (dg.READ_DIR, dg.WRITE_DIR)):
            return dg.flow_nack(op, rid, dg.NACK_MALFORMED)
        st = sess.by_id.get(sid)
        set_up = st is not None and st.state != "init"
        if op == dg.HEARTBEAT:
            if sid != 0 and not set_up:
                return dg.flow_nack(op, rid, dg.NACK_UNKNOWN_STREAM)
            t2 = body[4:12] if "heartbeat-t2-echo" in self.faults else struct.pack("!Q", arrival)
            return dg.flow_ack(op, rid, body[4:12] + t2 + struct.pack("!Q", dg.ntp_now()))
        direction = body[4]
        if st is None or not set_up:
            return dg.flow_nack(op, rid, dg.NACK_UNKNOWN_STREAM)
        carried = st.reads() if direction == dg.READ_DIR else st.writes()
        if not carried:
            return dg.flow_nack(op, rid, dg.NACK_UNKNOWN_STREAM)
        reading = direction == dg.READ_DIR
        if op == dg.GET_INTERVAL:
            value = st.read_us if reading else st.write_us
        elif op == dg.GET_TIMEOUT:
            value = st.read_timeout_us if reading else st.write_timeout_us
        else:
            (value,) = struct.unpack_from("!I", body, 5)
            # set-interval-write-acked: the client's own write interval is taken as ours to set
            peers = (op == dg.SET_INTERVAL) != reading
            if peers and not (op == dg.SET_INTERVAL and "set-interval-write-acked" in self.faults):
                return dg.flow_nack(op, rid, dg.NACK_NOT_PERMITTED)  # the peer owns that value
            if op == dg.SET_INTERVAL and not reading:
                st.write_us = value
            elif op == dg.SET_INTERVAL:
                shortest = dg.micros(st.access.read_interval or 0)
                if value < shortest and "accept-short-interval" not in self.faults:
                    return dg.flow_nack(op, rid, dg.NACK_REFUSED)
                if bugs.on("flow-top-bit-hang") and value >= 2**31 and st.state == "playing":
                    bugs.hang()  # the bug: the catch-up loop takes the interval as signed
                st.read_us = value
                st.next_send = min(st.next_send, asyncio.get_running_loop().time() + value / 1e6)
                self.reschedule(sess)
            else:
                times = 1 if "timeout-min-one-interval" in self.faults else 2
                if value < times * st.write_us:
                    return dg.flow_nack(op, rid, dg.NACK_REFUSED)
                if bugs.on("flow-top-bit-hang") and value >= 2**31 and st.state == "playing":
                    bugs.hang()  # the bug: the silence timer takes the timeout as signed
                st.write_timeout_us = value
        return dg.flow_ack(op, rid, struct.pack("!BI", direction, value))
