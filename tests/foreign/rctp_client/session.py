"""One RCTP/2.0 client session over asyncio: the control connection with requests in both
directions (D-RCTP-5, D-RCTP-6), the server's WRITE, STOP and BYE, the data stream
(D-RCTP-18 to D-RCTP-24) and the scenario an operator console runs."""

from __future__ import annotations

import asyncio
import contextlib
import os
import re
import struct
import sys
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import datastream as ds
import wire
from rcml import BadValue, Model, Node, decode_values, encode_values, is_xml_name, neutral, text
from wire import Message

USER_AGENT = "foreign-rctp-client/1.0"
REQUEST_TIMEOUT = 10.0  # no answer to one of our requests by then: give up the connection
BYE_WAIT = 5.0  # R-RCTP-23
HEARTBEAT_EVERY = 2.0  # well inside D-RCTP-24's 10 s
IDLE_WATCH = 1.0  # with no robot known: how long the session stays quiet before BYE
STREAM_TIME = 1.0
_SESSION = re.compile(r"([A-Za-z0-9$\-_.+]{8,64})(?:;[ \t]*timeout=([0-9]{1,5}))?")


class Closed(Exception):
    """The control connection is gone (or going)."""


class Stopping(Exception):
    """SIGINT or SIGTERM: end the session."""


@dataclass
class Url:
    host: str
    port: int
    path: str

    @classmethod
    def parse(cls, url: str) -> Url:
        m = re.fullmatch(
            r"rctp://(\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9.\-]+)(?::([0-9]{1,5}))?(/[^?#]*)?", url
        )
        if not m:
            raise ValueError(f"not an RCTP URL: {url}")
        port = int(m.group(2) or 7330)
        path = m.group(3) or "/"
        if not 1 <= port <= 65535 or wire.decode_target(path) is None:
            raise ValueError(f"bad port or site path in {url}")
        return cls(m.group(1).strip("[]"), port, path)


@dataclass
class Access:
    """An event or stream access on this side (D-RCTP-14)."""

    node: Node
    state: str = "init"
    stream_id: int = 0
    mode: str = ""
    reads: list[Node] = field(default_factory=list)
    writes: list[Node] = field(default_factory=list)
    read_interval: int = 0  # microseconds, in force
    write_interval: int = 0
    read_timeout: int = 0
    write_timeout: int = 0
    last_data: float = 0.0
    lost: bool = False
    values: dict[str, Any] = field(default_factory=dict)
    packets: int = 0
    sender: asyncio.Task[None] | None = None

    @property
    def stream(self) -> bool:
        return self.node.atype == "stream"


@dataclass
class FlowRequest:
    sid: int
    op: int
    body: bytes
    future: asyncio.Future[tuple[int, bytes] | None]
    sends: int = 1
    due: float = 0.0


class _Datagrams(asyncio.DatagramProtocol):
    def __init__(self, session: Session) -> None:
        self.session = session

    def datagram_received(self, data: bytes, addr: Any) -> None:
        self.session.on_datagram(data, addr)

    def error_received(self, exc: Exception) -> None:
        self.session.log(f"data stream: {exc}")


class Session:
    def __init__(
        self, url: Url, model: Model | None, faults: set[str], stop: asyncio.Event, verbose: bool
    ) -> None:
        self.url, self.model, self.faults = url, model, faults
        self.stop, self.verbose = stop, verbose
        self.play_time = STREAM_TIME
        self.reader: asyncio.StreamReader | None = None
        self.writer: asyncio.StreamWriter | None = None
        self.parser = wire.Parser(1 << 26 if "header-line-unbounded" in faults else wire.MAX_LINE)
        self.state = "idle"  # D-RCTP-13
        self.closed = False
        self.ended = asyncio.Event()
        self.sid = ""
        self.timeout = 60
        self.cseq = 0 if "cseq-starts-at-zero" in faults else 1
        self.pending: deque[tuple[int, str, asyncio.Future[Message], Callable[[Message], None]]]
        self.pending = deque()
        self.last_sent = time.monotonic()
        self.last_server_request = 0.0
        self.accesses: dict[str, Access] = {}
        self.held: list[str] = []
        self.refusals: list[str] = []
        self.tasks: list[asyncio.Task[Any]] = []
        # the data stream
        self.udp: asyncio.DatagramTransport | None = None
        self.udp_port = 0
        self.server_ip = ""
        self.server_port = 0
        self.tag: int | None = None
        self.seq = 0 if "seq-starts-at-zero" in faults else int.from_bytes(os.urandom(2), "big")
        self.order = ds.Order(zero_is_newer="apply-duplicate-packets" in faults)
        self.answers = ds.AnswerCache()
        self.flow: dict[int, FlowRequest] = {}
        self.rid = 1
        self.last_heartbeat = 0.0
        self.clock = ds.Clock(model.time_precision if model else 0.0)
        self.dropped = 0

    # ---- plumbing ---------------------------------------------------------------------------

    def log(self, what: str, always: bool = False) -> None:
        if self.verbose or always:
            print(f"{time.strftime('%H:%M:%S')} {what}", file=sys.stderr, flush=True)

    def _spawn(self, coro: Any) -> None:
        self.tasks.append(asyncio.get_running_loop().create_task(coro))

    def _send(self, data: bytes) -> None:
        if self.writer is not None and not self.closed:
            self.writer.write(data)

    def close(self, why: str) -> None:
        if self.closed:
            return
        self.closed = True
        self.state = "closed"
        self.log(f"connection closed: {why}")
        for _cseq, _method, fut, _on_ok in self.pending:
            if not fut.done():
                fut.set_exception(Closed(why))
        self.pending.clear()
        for fr in self.flow.values():
            if not fr.future.done():
                fr.future.set_result(None)
        self.flow.clear()
        for acc in self.accesses.values():
            self._stop_sender(acc)
        if self.writer is not None:
            self.writer.close()
        if self.udp is not None:
            self.udp.close()
        self.ended.set()

    async def open(self) -> None:
        reader, writer = await asyncio.wait_for(
            asyncio.open_connection(self.url.host, self.url.port), 3.0
        )
        self.reader, self.writer = reader, writer
        self.server_ip = writer.get_extra_info("peername")[0]
        self._spawn(self._read_loop())
        self._spawn(self._housekeeping())

    async def _read_loop(self) -> None:
        assert self.reader is not None
        assert self.writer is not None
        why = "the server closed the connection"
        try:
            while not self.closed:
                data = await self.reader.read(65536)
                if not data:
                    break
                self.parser.feed(data)
                if not self._drain_parser():
                    return
                await self.writer.drain()
        except (ConnectionError, OSError) as e:
            why = f"connection error: {e}"
        finally:
            self.close(why)

    def _drain_parser(self) -> bool:
        """Handle every whole message received; False once the connection must close."""
        while not self.closed:
            try:
                msg = self.parser.next()
            except wire.FrameError as e:
                if "skip-bad-response" in self.faults and e.status is None:
                    self.parser.discard()
                    continue
                if e.status is not None:  # a request that cannot be framed (R-RCTP-8)
                    fields = [("CSeq", str(e.cseq))] if e.cseq is not None else []
                    self._send(wire.response(e.status, fields + self._session_field()))
                self.close(f"a message that cannot be framed: {e}")
                return False
            if msg is None:
                return True
            if msg.request:
                self.on_request(msg)
            else:
                self.on_response(msg)
        return False

    def _session_field(self) -> list[tuple[str, str]]:
        return [("Session", self.sid)] if self.sid else []

    # ---- our requests -----------------------------------------------------------------------

    async def call(
        self,
        method: str,
        target: str,
        fields: list[tuple[str, str]] | None = None,
        body: bytes = b"",
        on_ok: Callable[[Message], None] | None = None,
        needed: bool = True,
    ) -> Message:
        if self.closed or (self.state != "open" and method not in ("CONNECT", "BYE")):
            raise Closed("no session")
        cseq = self.cseq
        self.cseq += 1
        head = [("CSeq", str(cseq))]
        if self.sid:
            head.append(("Session", self.sid))
        if method == "CONNECT":
            head.append(("User-Agent", USER_AGENT))
        head += fields or []
        if body:
            head += [("Content-Type", wire.VALUES), ("Content-Length", str(len(body)))]
        fut: asyncio.Future[Message] = asyncio.get_running_loop().create_future()
        self.pending.append((cseq, method, fut, on_ok or (lambda m: None)))
        eol = "User-Agent" if "bare-lf-user-agent" in self.faults else ""
        self._send(
            wire.build(f"{method} {wire.encode_path(target)} {wire.VERSION}", head, body, eol)
        )
        self.last_sent = time.monotonic()
        self.log(f"-> {method} {target} (CSeq {cseq})")
        try:
            msg = await asyncio.wait_for(asyncio.shield(fut), REQUEST_TIMEOUT)
        except TimeoutError:
            self.close(f"no answer to {method} in {REQUEST_TIMEOUT} s")
            raise Closed("no answer") from None
        self.log(f"<- {msg.status} {msg.reason} for {method} {target}")
        if msg.status != 200 and needed:
            self.refusals.append(f"{method} {target}: {msg.status} {msg.reason}")
            self.log(f"{method} {target} refused: {msg.status} {msg.reason}", always=True)
        return msg

    def on_response(self, msg: Message) -> None:
        if not self.pending:
            self.close("a response to no request of ours")
            return
        cseq, _method, fut, on_ok = self.pending[0]
        if "accept-any-cseq" not in self.faults and (
            msg.cseq() != cseq or msg.version != wire.VERSION
        ):
            self.close(f"a response with CSeq {msg.get('CSeq')!r} to our CSeq {cseq}")
            return
        self.pending.popleft()
        if msg.status == 200:
            on_ok(msg)  # states change when the answer arrives (D-RCTP-13, D-RCTP-14)
        if not fut.done():
            fut.set_result(msg)

    # ---- the server's requests --------------------------------------------------------------

    def on_request(self, msg: Message) -> None:
        self.last_server_request = time.monotonic()
        self.log(f"<= {msg.summary()} (CSeq {msg.get('CSeq')})")
        if msg.method == "BYE" and "bye-unanswered" in self.faults:
            self.close("the server said BYE")
            return
        status, extra = self._check(msg)
        cseq = msg.cseq()
        if "answer-own-cseq" in self.faults:
            cseq = self.cseq - 1
        fields = ([("CSeq", str(cseq))] if cseq is not None else []) + self._session_field() + extra
        answer = wire.response(status, fields)
        self.log(f"=> {status} for {msg.summary()}")
        if "stop-answered-late" in self.faults and msg.method == "STOP":
            asyncio.get_running_loop().call_later(0.05, self._send, answer)
        else:
            self._send(answer)
        if msg.method == "BYE" and status == 200:
            self.state = "closing"
            self.log(f"the server ended the session (Reason: {msg.get('Reason')})", always=True)
            self._spawn(self._close_after(BYE_WAIT, "the server's BYE answered"))

    def _check(self, msg: Message) -> tuple[int, list[tuple[str, str]]]:
        """The answer's status, the checks in D-RCTP-25's order."""
        if msg.method not in wire.METHODS:
            return (400 if "unknown-method-400" in self.faults else 501), []
        if msg.version != wire.VERSION and "version-not-checked" not in self.faults:
            return 505, []
        if msg.cseq() is None and "missing-cseq-ignored" not in self.faults:
            return 400, []
        if any(len(msg.all(name)) > 1 for name in wire.ONCE):
            return 400, []
        if msg.method not in ("WRITE", "STOP", "BYE"):  # D-RCTP-12: not the server's to send
            return 405, [("Allow", "WRITE, STOP, BYE")]
        segments = None if msg.target == "*" else wire.decode_target(msg.target)
        if msg.target != "*" and segments is None:
            return 400, []
        if self.state == "idle" or not self.sid:
            return 454, []
        named = (msg.get("Session") or "").split(";")[0].strip()
        if named != self.sid and "session-not-checked" not in self.faults:
            return 454, []
        if self.state != "open":
            return 455, []
        path = "*" if segments is None else "/" + "/".join(segments)
        if msg.method == "BYE":
            return (200, []) if path == "*" else (405, [("Allow", "WRITE, STOP")])
        acc = self.accesses.get(path)
        if msg.method == "STOP":
            if acc is None or acc.state == "init":
                return 455, []
            self._to_init(acc)
            reason = msg.get("Reason")
            self.log(f"the server stopped {path} (Reason: {reason})", always=reason == "timeout")
            return 200, []
        if acc is None or acc.stream or acc.state != "playing":
            return 455, []
        return self._server_write(acc, msg), []

    def _server_write(self, acc: Access, msg: Message) -> int:
        """A data-change event (D-RCTP-27): the values all applied, or 400."""
        if msg.get("Content-Length") is None:
            return 411
        if (msg.get("Content-Type") or "").lower() != wire.VALUES:
            return 415
        nodes = self._nodes(acc.node, msg.get("Nodes"))
        if nodes is None:
            return 400
        try:
            values = decode_values(nodes, msg.body)
        except BadValue:
            return 400
        for node, value in zip(nodes, values, strict=True):
            acc.values[node.name] = value
        self.log(
            "event "
            + ", ".join(f"{n.path} = {text(v)}" for n, v in zip(nodes, values, strict=True))
        )
        return 200

    def _nodes(self, access: Node, field_value: str | None) -> list[Node] | None:
        """A Nodes field's data nodes of `access`, each once in canonical order (R-RCTP-30)."""
        if field_value is None:
            return None
        out: list[Node] = []
        for raw in field_value.split(","):
            name = raw.strip(" \t")
            segs = wire.decode_target("/" + name)
            if not segs or len(segs) != 1 or not is_xml_name(segs[0]):
                return None
            node = access.children.get(segs[0])
            if node is None or node.kind != "data":
                return None
            if out and out[-1].name.encode() >= node.name.encode():
                return None
            out.append(node)
        return out

    async def _close_after(self, delay: float, why: str) -> None:
        try:
            await asyncio.wait_for(self.ended.wait(), delay)
        except TimeoutError:
            self.close(why)

    # ---- session methods --------------------------------------------------------------------

    async def connect(self) -> bool:
        def opened(msg: Message) -> None:
            m = _SESSION.fullmatch(msg.get("Session") or "")
            if m is None:
                self.close("CONNECT answered 200 without a valid Session (R-RCTP-18)")
                return
            self.sid, self.timeout = m.group(1), int(m.group(2) or 60)
            self.state = "open"

        msg = await self.call("CONNECT", self.url.path, on_ok=opened)
        if msg.status == 200 and self.state == "open":
            self.log(f"session {self.sid}, timeout {self.timeout} s")
            return True
        return False

    async def bye(self) -> None:
        if self.closed or self.state != "open":
            return
        self.state = "closing"  # BYE sent (D-RCTP-13)
        with contextlib.suppress(TimeoutError, Closed):
            await asyncio.wait_for(self.call("BYE", "*", needed=False), BYE_WAIT)
        if "bye-not-closed" in self.faults:
            await self._close_after(30.0, "the server kept the connection open")
        self.close("BYE")

    async def _refresh(self) -> None:
        with contextlib.suppress(Closed):
            await self.call("CONNECT", self.url.path, needed=False)

    def _check_stop(self) -> None:
        if self.stop.is_set():
            raise Stopping
        if self.closed or self.state != "open":
            raise Closed("the session ended")

    async def watch(self, idle: float, at_most: float = 30.0) -> None:
        """Answer the server until it has been quiet for `idle` seconds."""
        start = time.monotonic()
        while not self.closed and not self.stop.is_set():
            now = time.monotonic()
            if now - max(start, self.last_server_request) >= idle or now - start >= at_most:
                return
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(self.ended.wait(), 0.05)

    # ---- the privilege and the values --------------------------------------------------------

    async def acquire(self, path: str) -> bool:
        if any(path == h or path.startswith(h.rstrip("/") + "/") for h in self.held):
            return True
        msg = await self.call("ACQUIRE", path)
        if msg.status == 200:
            self.held.append(path)
        return msg.status == 200

    async def read(self, node: Node) -> list[tuple[Node, Any]]:
        msg = await self.call("READ", node.path)
        if msg.status != 200:
            return []
        if node.kind == "data":
            nodes: list[Node] | None = [node]
        else:
            nodes = self._nodes(node, msg.get("Nodes"))
        try:
            if nodes is None:
                raise BadValue("no usable Nodes field")
            values = decode_values(nodes, msg.body)
        except BadValue as e:
            self.refusals.append(f"READ {node.path}: a body that does not decode ({e})")
            return []
        for n, v in zip(nodes, values, strict=True):
            self.log(f"  {n.path} = {text(v)}")
        return list(zip(nodes, values, strict=True))

    async def write(self, node: Node, known: dict[str, Any]) -> None:
        if node.kind == "data":
            nodes, fields = [node], []
        else:
            nodes = node.data_nodes("w")
            if "nodes-document-order" in self.faults:
                nodes.sort(key=lambda n: n.doc_index)
            names = ", ".join(wire.encode_segment(n.name) for n in nodes)
            fields = [("Nodes", names)]
        values = [known.get(n.path, neutral(n)) for n in nodes]
        body = encode_values(nodes, values, "int16-little-endian" in self.faults)
        await self.call("WRITE", node.path, fields, body)

    # ---- event and stream accesses ----------------------------------------------------------

    def _to_init(self, acc: Access) -> None:
        acc.state = "init"
        self._stop_sender(acc)

    def _stop_sender(self, acc: Access) -> None:
        if acc.sender is not None:
            acc.sender.cancel()
            acc.sender = None

    async def setup(self, node: Node, mode: str = "") -> Access | None:
        acc = self.accesses.setdefault(node.path, Access(node))
        fields = []
        if node.atype == "stream":
            if self.udp is None:
                await self._open_udp()
            fields = [("Transport", f"udp;client_port={self.udp_port};mode={mode}")]

        def ready(msg: Message) -> None:
            if node.atype == "stream" and not self._transport(acc, mode, msg.get("Transport")):
                self.log(f"SETUP {node.path}: unusable Transport {msg.get('Transport')!r}", True)
                acc.state = "ready"
                acc.mode = ""
                return
            acc.state = "ready"

        msg = await self.call("SETUP", node.path, fields, on_ok=ready)
        return acc if msg.status == 200 else None

    def _transport(self, acc: Access, mode: str, value: str | None) -> bool:
        params: dict[str, str] = {}
        parts = (value or "").split(";")
        if parts[0].strip() != "udp":
            return False
        for part in parts[1:]:
            key, _, val = part.strip().partition("=")
            params[key] = val
        try:
            port, sid = int(params["server_port"]), int(params["stream"])
            if not re.fullmatch(r"[0-9A-Fa-f]{8}", params["tag"]) or not 1 <= port <= 65535:
                return False
            if not 1 <= sid <= 255:
                return False
        except (KeyError, ValueError):
            return False
        self.tag, self.server_port = int(params["tag"], 16), port
        first = acc.stream_id == 0
        acc.stream_id, acc.mode = sid, params.get("mode", mode)
        node = acc.node
        acc.reads = node.data_nodes("r") if acc.mode in ("read", "both") else []
        acc.writes = node.data_nodes("w") if acc.mode in ("write", "both") else []
        if first:  # a stream keeps its intervals and timeouts when set up again (D-RCTP-28)
            acc.read_interval = ds.micros(node.timing.get("readInterval", 0.0))
            acc.write_interval = ds.micros(node.timing.get("writeInterval", 0.0))
            acc.read_timeout = ds.micros(node.timing.get("readTimeout", 10.0))
            acc.write_timeout = ds.micros(node.timing.get("writeTimeout", 10.0))
        return True

    async def go(self, acc: Access) -> bool:
        def playing(_msg: Message) -> None:
            acc.state = "playing"
            acc.last_data = time.monotonic()
            acc.lost = False
            if acc.stream and acc.writes and acc.sender is None and acc.write_interval > 0:
                acc.sender = asyncio.get_running_loop().create_task(self._sender(acc))
            self.last_heartbeat = 0.0

        return (await self.call("GO", acc.node.path, on_ok=playing)).status == 200

    async def pause(self, acc: Access) -> None:
        def paused(_msg: Message) -> None:
            acc.state = "ready"
            if "data-after-pause" not in self.faults:
                self._stop_sender(acc)

        await self.call("PAUSE", acc.node.path, on_ok=paused)

    async def stop_access(self, acc: Access) -> None:
        await self.call("STOP", acc.node.path, on_ok=lambda _m: self._to_init(acc))

    # ---- the data stream --------------------------------------------------------------------

    async def _open_udp(self) -> None:
        assert self.writer is not None
        local = self.writer.get_extra_info("sockname")[0]
        loop = asyncio.get_running_loop()
        transport, _ = await loop.create_datagram_endpoint(
            lambda: _Datagrams(self), local_addr=(local, 0)
        )
        self.udp = transport
        self.udp_port = transport.get_extra_info("sockname")[1]

    def _send_packet(self, payloads: list[tuple[int, int, bytes]]) -> None:
        if self.udp is None or self.tag is None or self.closed:
            return
        ts = ds.ntp_now()
        self.udp.sendto(
            ds.build_packet(self.seq, self.tag, ts, payloads), (self.server_ip, self.server_port)
        )
        self.seq = (self.seq + 1) % 65536
        self.last_sent = time.monotonic()

    async def _sender(self, acc: Access) -> None:
        """DATA of a writing stream once per write interval while it plays (R-RCTP-44)."""
        loop = asyncio.get_running_loop()
        due = loop.time()
        le16 = "int16-little-endian" in self.faults
        while not self.closed:
            values = [acc.values.get(n.name, neutral(n)) for n in acc.writes]
            self._send_packet([(ds.DATA, acc.stream_id, encode_values(acc.writes, values, le16))])
            interval = max(acc.write_interval, 1000) / 1e6
            due += interval
            now = loop.time()
            if due < now - interval:
                due = now
            await asyncio.sleep(max(0.0, due - now))

    def on_datagram(self, data: bytes, addr: Any) -> None:
        t2 = ds.ntp_now("heartbeat-unix-epoch" in self.faults)
        if self.tag is None or self.closed:
            return
        checks = "tag-not-checked" not in self.faults
        if checks and (addr[0] != self.server_ip or addr[1] != self.server_port):
            self.dropped += 1
            return
        packet = ds.parse_packet(data)
        if packet is None or (checks and packet.tag != self.tag):
            self.dropped += 1
            return
        newer = self.order.newer(packet.seq)
        answers = []
        for ptype, sid, body in packet.payloads:
            if ptype == ds.DATA and newer:
                self._on_data(sid, body)
            elif ptype == ds.FLOW:
                answer = self._on_flow(sid, body, t2)
                if answer is not None:
                    answers.append(answer)
        if answers:
            self._send_packet(answers)

    def _by_stream(self, sid: int) -> Access | None:
        for acc in self.accesses.values():
            if acc.stream and acc.stream_id == sid and sid and acc.state != "init":
                return acc
        return None

    def _on_data(self, sid: int, body: bytes) -> None:
        acc = self._by_stream(sid)
        if acc is None or not acc.reads:
            return
        try:
            values = decode_values(acc.reads, body)
        except BadValue:
            return  # never apply part of a payload (R-RCTP-58)
        for node, value in zip(acc.reads, values, strict=True):
            acc.values[node.name] = value
        acc.packets += 1
        acc.last_data = time.monotonic()
        if acc.lost:
            self.log(f"stream {acc.node.path} receives again", always=True)
            acc.lost = False

    def _on_flow(self, sid: int, body: bytes, t2: int) -> tuple[int, int, bytes] | None:
        if len(body) < 4:
            return None
        message, op, rid = struct.unpack_from("!BBH", body)
        if message == ds.REQUEST:
            cached = self.answers.get(rid)
            if cached is not None and "flow-repeat-recomputed" not in self.faults:
                return (ds.FLOW, cached[0], cached[1])
            answer = self._answer_flow(sid, op, rid, body[4:], t2)
            self.answers.put(rid, sid, answer)
            return (ds.FLOW, sid, answer)
        if message in (ds.ACK, ds.NACK):
            self._on_flow_answer(message, op, rid, body[4:])
        return None

    def _answer_flow(self, sid: int, op: int, rid: int, fields: bytes, t2: int) -> bytes:
        """ACK or NACK of the server's FLOW request (D-RCTP-22, R-RCTP-46, R-RCTP-53)."""
        if op not in (1, 2, 3, 4, 5):
            reason = ds.MALFORMED if "unknown-op-nack-5" in self.faults else ds.UNKNOWN_OP
            return ds.nack(op, rid, reason)
        if op == ds.HEARTBEAT:
            if len(fields) != 8:
                return ds.nack(op, rid, ds.MALFORMED)
            t3 = ds.ntp_now("heartbeat-unix-epoch" in self.faults)
            return ds.flow_body(ds.ACK, op, rid, fields + struct.pack("!QQ", t2, t3))
        size = 1 if op in (ds.GET_INTERVAL, ds.GET_TIMEOUT) else 5
        if len(fields) != size or fields[0] not in (ds.READ_DIR, ds.WRITE_DIR):
            return ds.nack(op, rid, ds.MALFORMED)
        direction = fields[0]
        acc = self._by_stream(sid)
        if acc is None or not (acc.reads if direction == ds.READ_DIR else acc.writes):
            return ds.nack(op, rid, ds.UNKNOWN_STREAM)
        reading = direction == ds.READ_DIR
        if op == ds.GET_INTERVAL:
            value = acc.read_interval if reading else acc.write_interval
        elif op == ds.GET_TIMEOUT:
            value = acc.read_timeout if reading else acc.write_timeout
        else:
            (value,) = struct.unpack_from("!I", fields, 1)
            # the sender owns an interval, the receiver a timeout: ours are write, read
            if (op == ds.SET_INTERVAL) == reading:
                return ds.nack(op, rid, ds.NOT_PERMITTED)
            if op == ds.SET_INTERVAL:
                if value < ds.micros(acc.node.timing.get("writeInterval", 0.0)):
                    return ds.nack(op, rid, ds.REFUSED)
                acc.write_interval = value
            else:
                if value < 2 * acc.read_interval:
                    return ds.nack(op, rid, ds.REFUSED)
                acc.read_timeout = value
        return ds.flow_body(ds.ACK, op, rid, struct.pack("!BI", direction, value))

    def _on_flow_answer(self, message: int, op: int, rid: int, fields: bytes) -> None:
        request = self.flow.get(rid)
        if request is None or request.op != op:
            return
        if message == ds.NACK:
            if len(fields) != 1:
                return
        elif op == ds.HEARTBEAT:
            if len(fields) != 24 or fields[:8] != request.body[4:12]:
                return
            t4 = time.time()
            t1, t2, t3 = struct.unpack("!QQQ", fields)
            self.clock.add(ds.ntp_to_unix(t1), ds.ntp_to_unix(t2), ds.ntp_to_unix(t3), t4)
        elif len(fields) != 5:
            return
        del self.flow[rid]
        if not request.future.done():
            request.future.set_result((message, fields))

    def flow_request(self, sid: int, op: int, fields: bytes) -> asyncio.Future[Any]:
        rid = self.rid
        self.rid = (self.rid + 1) % 65536
        body = ds.flow_body(ds.REQUEST, op, rid, fields)
        fut: asyncio.Future[tuple[int, bytes] | None]
        fut = asyncio.get_running_loop().create_future()
        self.flow[rid] = FlowRequest(sid, op, body, fut, due=time.monotonic() + 0.25)
        self._send_packet([(ds.FLOW, sid, body)])
        return fut

    def _heartbeat(self) -> None:
        self.last_heartbeat = time.monotonic()
        self.flow_request(0, ds.HEARTBEAT, struct.pack("!Q", ds.ntp_now()))

    async def _housekeeping(self) -> None:
        """Retransmit FLOW requests, send heartbeats, watch receive timeouts, keep alive."""
        while not self.closed:
            await asyncio.sleep(0.05)
            now = time.monotonic()
            for rid, request in list(self.flow.items()):
                if now < request.due:
                    continue
                if request.sends >= 5:  # D-RCTP-22: five sends, then no answer
                    del self.flow[rid]
                    request.future.set_result(None)
                    continue
                request.sends += 1
                request.due = now + 0.25
                self._send_packet([(ds.FLOW, request.sid, request.body)])
            playing = [a for a in self.accesses.values() if a.stream and a.state == "playing"]
            if playing and self.tag is not None and now - self.last_heartbeat >= HEARTBEAT_EVERY:
                self._heartbeat()
            for acc in playing:
                if acc.reads and not acc.lost and now - acc.last_data > acc.read_timeout / 1e6:
                    acc.lost = True  # D-RCTP-23: reported; the server will STOP it
                    self.log(f"stream {acc.node.path}: nothing for its read timeout", always=True)
            if self.state == "open" and now - self.last_sent >= self.timeout / 3:
                self.last_sent = now
                self._spawn(self._refresh())

    # ---- the scenario -----------------------------------------------------------------------

    async def run(self) -> bool:
        """Connect, run the scenario, say BYE. True when nothing needed was refused."""
        completed = False
        try:
            if not await self.connect():
                return False
            if self.model is None:
                await self.watch(IDLE_WATCH)
            else:
                await self._robot()
            completed = not self.closed and self.state == "open"
        except Stopping:
            completed = True
        except Closed as e:
            self.log(f"session ended early: {e}", always=True)
        finally:
            await self.bye()
            self.close("done")
            for task in self.tasks:
                task.cancel()
            await asyncio.gather(*self.tasks, return_exceptions=True)
        return completed and not self.refusals

    async def _robot(self) -> None:
        assert self.model is not None
        nodes = self.model.root.walk()
        datas = [n for n in nodes if n.kind == "data" and n.parent and n.parent.atype == "normal"]
        events = [n for n in nodes if n.kind == "access" and n.atype == "event"][:3]
        streams = [n for n in nodes if n.kind == "access" and n.atype == "stream"][:2]
        known: dict[str, Any] = {}
        for node in [d for d in datas if d.readable][:8] + [e for e in events if e.data_nodes("r")]:
            self._check_stop()
            known.update((n.path, v) for n, v in await self.read(node))
        writable = next((d for d in datas if d.writable), None)
        for node in ([writable] if writable else []) + [e for e in events if e.data_nodes("w")]:
            self._check_stop()
            if await self.acquire(node.path):
                await self.write(node, known)
        playing: list[Access] = []
        for node in [e for e in events if e.data_nodes("r")]:
            self._check_stop()
            acc = await self.setup(node)
            if acc is not None and await self.go(acc):
                playing.append(acc)
                await self.read(node)  # GO sends nothing by itself (D-RCTP-27)
        for node in streams:
            self._check_stop()
            reads = bool(node.data_nodes("r")) and "readInterval" in node.timing
            writes = bool(node.data_nodes("w")) and "writeInterval" in node.timing
            if writes and not await self.acquire(node.path):
                writes = False
            mode = "both" if reads and writes else "read" if reads else "write" if writes else ""
            if not mode:
                continue
            acc = await self.setup(node, mode)
            if acc is not None and acc.mode and await self.go(acc):
                playing.append(acc)
                direction = ds.READ_DIR if acc.reads else ds.WRITE_DIR
                self.flow_request(acc.stream_id, ds.GET_INTERVAL, bytes([direction]))
        await self.watch(self.play_time, self.play_time)
        self._check_stop()
        for acc in playing:
            if acc.stream and acc.state == "playing":
                await self.pause(acc)
                self.log(f"stream {acc.node.path}: {acc.packets} DATA payloads received")
            if acc.state != "init":
                await self.stop_access(acc)
        estimate = self.clock.estimate()
        if estimate is not None:
            self.log(f"robot clock offset {estimate[0]:+.6f} s ± {estimate[1]:.6f} s")
        if self.held:
            await self.call("RELEASE", "*")
            self.held.clear()
