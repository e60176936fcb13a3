"""One RCTP/2.0 client session over asyncio: the control connection with requests in both
directions (D-RCTP-5, D-RCTP-6), the server's WRITE, STOP and BYE (D-RCTP-12), and the data
stream with its FLOW answers, heartbeats and clock samples (D-RCTP-18 to D-RCTP-24). What the
client asks for, and when, is scenario.py's business."""

from __future__ import annotations

import asyncio
import contextlib
import math
import os
import re
import struct
import sys
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import bugs
import datastream as ds
import wire
from rcml import BadValue, Codec, Model, Node, is_xml_name, text, zero
from wire import Message

USER_AGENT = "foreign-rctp-client/2.0"
REQUEST_TIMEOUT = 5.0  # D-RCTP-31: no answer within 5 s ends the run
BYE_WAIT = 5.0  # R-RCTP-23
HEARTBEAT_EVERY = 1.0  # D-RCTP-31 step 6
FLOW_RETRY = 0.25  # D-RCTP-22
FLOW_SENDS = 5
_ASCII_LOWER = str.maketrans("ABCDEFGHIJKLMNOPQRSTUVWXYZ", "abcdefghijklmnopqrstuvwxyz")
_SESSION = re.compile(r"([A-Za-z0-9$\-_.+]{8,64})(?:;[ \t]*(?i:timeout)=([0-9]{1,5}))?")


class Closed(Exception):
    """The control connection is gone, or a request went unanswered for 5 s."""


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
        if not 1 <= port <= 65534 or wire.decode_target(path) is None:
            raise ValueError(f"bad port or site path in {url}")
        return cls(m.group(1).strip("[]"), port, path)

    def http(self, path: str) -> str:
        """The robot's files (D-RCTP-29): HTTP on the port after the RCTP port."""
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"http://{host}:{self.port + 1}{path}"


@dataclass
class Access:
    """An event or stream access on this side (D-RCTP-14)."""

    node: Node
    state: str = "init"
    stopped: bool = False  # the server STOPped it during its step
    usable: bool = True
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
    values: dict[str, Any] = field(default_factory=dict)  # newest DATA applied, by node name
    packets: int = 0
    sender: asyncio.Task[None] | None = None
    beater: asyncio.Task[None] | None = None

    @property
    def stream(self) -> bool:
        return self.node.atype == "stream"


@dataclass
class FlowRequest:
    sid: int
    op: int
    body: bytes
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
        self, url: Url, model: Model, faults: set[str], stop: asyncio.Event, verbose: bool
    ) -> None:
        self.url, self.model, self.faults = url, model, faults
        self.stop, self.verbose = stop, verbose
        self.codec = Codec(faults)
        self.reader: asyncio.StreamReader | None = None
        self.writer: asyncio.StreamWriter | None = None
        self.parser = wire.Parser(1 << 26 if "header-line-unbounded" in faults else wire.MAX_LINE)
        self.state = "idle"  # D-RCTP-13
        self.closed = False
        self.ended = asyncio.Event()
        self.wake = asyncio.Event()  # something the scenario may wait for happened
        self.sid = ""
        self.timeout = 60
        self.cseq = 0 if "cseq-starts-at-zero" in faults else 1
        self.pending: deque[tuple[int, asyncio.Future[Message], Callable[[Message], None]]]
        self.pending = deque()
        self.last_sent = time.monotonic()
        self.accesses: dict[str, Access] = {}
        self.values: dict[str, Any] = {}  # newest value known of normal and event nodes
        self.tasks: list[asyncio.Task[Any]] = []
        # the data stream
        self.udp: asyncio.DatagramTransport | None = None
        self.udp_port = 0
        self.server_ip = ""
        self.server_port = 0
        self.tag: int | None = None
        self.seq = 0 if "seq-starts-at-zero" in faults else int.from_bytes(os.urandom(2), "big")
        self.flow_seq = int.from_bytes(os.urandom(2), "big")  # seq-separate-flow-counter
        self.order = ds.Order(zero_is_newer="apply-duplicate-packets" in faults)
        self.answers = ds.AnswerCache()
        self.flow: dict[int, FlowRequest] = {}
        self.rid = int.from_bytes(os.urandom(2), "big")
        self.clock = ds.Clock(model.time_precision)

    # ---- plumbing ---------------------------------------------------------------------------

    def log(self, what: str, always: bool = False) -> None:
        if self.verbose or always:
            print(f"{time.strftime('%H:%M:%S')} {what}", file=sys.stderr, flush=True)

    def poke(self) -> None:
        self.wake.set()

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
        for _cseq, fut, _on_ok in self.pending:
            if not fut.done():
                fut.set_exception(Closed(why))
        self.pending.clear()
        self.flow.clear()
        for acc in self.accesses.values():
            _cancel(acc.sender)
            _cancel(acc.beater)
        if self.writer is not None:
            self.writer.close()
        if self.udp is not None:
            self.udp.close()
        self.ended.set()
        self.poke()

    async def finish(self) -> None:
        self.close("done")
        for task in self.tasks:
            task.cancel()
        await asyncio.gather(*self.tasks, return_exceptions=True)

    async def open(self) -> None:
        reader, writer = await asyncio.wait_for(
            asyncio.open_connection(self.url.host, self.url.port), REQUEST_TIMEOUT
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

    async def wait(self, seconds: float, acc: Access | None = None) -> bool:
        """Sleep, answering the server meanwhile; False as soon as the run must stop (the
        session is ending, a signal) or the server STOPs `acc`."""
        loop = asyncio.get_running_loop()
        end = loop.time() + seconds
        while not (self.interrupted() or (acc is not None and acc.stopped)):
            left = end - loop.time()
            if left <= 0:
                return True
            self.wake.clear()
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(self.wake.wait(), left)
        return False

    def interrupted(self) -> bool:
        return self.closed or self.state != "open" or self.stop.is_set()

    # ---- our requests -----------------------------------------------------------------------

    async def call(
        self,
        method: str,
        target: str,
        fields: list[tuple[str, str]] | None = None,
        body: bytes = b"",
        on_ok: Callable[[Message], None] | None = None,
    ) -> Message:
        """Send a request and wait for its answer; Closed when the connection is gone or the
        answer does not come within 5 s (the connection is then closed)."""
        after_bye = self.state == "closing" and "request-after-bye" in self.faults
        if self.closed or not (
            self.state == "open" or (self.state == "idle" and method == "CONNECT") or after_bye
        ):
            raise Closed("no session")
        cseq = self.cseq
        if not (method == "WRITE" and "cseq-reused-after-write" in self.faults):
            self.cseq += 1
        head = [("CSeq", str(cseq))]
        bare = method in ("GO", "PAUSE", "STOP") and "session-missing-on-stream-methods" in (
            self.faults
        )
        if self.sid and not bare:
            head.append(("Session", self.sid))
        if method == "CONNECT":
            head.append(("User-Agent", USER_AGENT))
        head += fields or []
        if body:
            untyped = "event-write-no-content-type" in self.faults and any(
                k == "Nodes" for k, _ in head
            )  # the fault: the event WRITE's body goes untyped
            if not untyped:
                head.append(("Content-Type", wire.VALUES))
            head.append(("Content-Length", str(len(body))))
        fut: asyncio.Future[Message] = asyncio.get_running_loop().create_future()
        self.pending.append((cseq, fut, on_ok or (lambda m: None)))
        eol = "User-Agent" if "bare-lf-user-agent" in self.faults else ""
        if method == "BYE":
            self.state = "closing"  # BYE sent (D-RCTP-13)
        self._send(
            wire.build(f"{method} {wire.encode_path(target)} {wire.VERSION}", head, body, eol)
        )
        self.last_sent = time.monotonic()
        self.log(f"-> {method} {target} (CSeq {cseq})")
        try:
            msg = await asyncio.wait_for(asyncio.shield(fut), REQUEST_TIMEOUT)
        except TimeoutError:
            fut.cancel()
            self.close(f"no answer to {method} {target} in {REQUEST_TIMEOUT:g} s")
            raise Closed("no answer") from None
        self.log(f"<- {msg.status} {msg.reason} for {method} {target}")
        return msg

    def on_response(self, msg: Message) -> None:
        if not self.pending:
            self.close("a response to no request of ours")
            return
        cseq, fut, on_ok = self.pending[0]
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
            self.poke()

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
                # stray-stop-200: the bug answers any STOP while something plays
                playing = any(a.state == "playing" for a in self.accesses.values())
                if bugs.on("stray-stop-200") and playing:
                    return 200, []
                return 455, []
            self._to_init(acc)
            acc.stopped = True
            self.poke()
            self.log(f"the server stopped {path} (Reason: {msg.get('Reason')})", always=True)
            return 200, []
        # write-while-paused-taken: only an access in init refuses the push
        taking = ("init",) if "write-while-paused-taken" in self.faults else ("ready", "init")
        if acc is None or acc.stream or acc.state in taking:
            return 455, []
        return self._server_write(acc, msg), []

    def is_values(self, ctype: str | None) -> bool:
        """Whether a Content-Type is application/rctp-values, in any ASCII letter case
        (D-RCTP-30), or exactly with the fault media-type-exact."""
        if "media-type-exact" in self.faults:
            return ctype == wire.VALUES
        return (ctype or "").translate(_ASCII_LOWER) == wire.VALUES

    def _server_write(self, acc: Access, msg: Message) -> int:
        """A data-change event (D-RCTP-27): the values all taken, or an error status."""
        if msg.get("Content-Length") is None:
            return 411
        if not self.is_values(msg.get("Content-Type")):
            return 415
        nodes = self.nodes_field(acc.node, msg.get("Nodes"))
        if nodes is None:
            return 400
        if "refused-push-taken" in self.faults:
            with contextlib.suppress(BadValue):
                raw = self.codec.decode(nodes, msg.body, ranged=False)
                self.values.update((n.path, v) for n, v in zip(nodes, raw, strict=True))
        try:
            values = self.codec.decode(nodes, msg.body)
        except BadValue as exc:
            if bugs.on("bad-push-crash") and acc.state == "playing":
                bugs.crash(exc)  # the bug: the event handler lets the decoder's error escape
            return 400
        for node, value in zip(nodes, values, strict=True):
            self.values[node.path] = value
        self.log(
            "event "
            + ", ".join(f"{n.path} = {text(v)}" for n, v in zip(nodes, values, strict=True))
        )
        return 200

    def nodes_field(self, access: Node, field_value: str | None) -> list[Node] | None:
        """A Nodes field's data nodes of `access`, each once in canonical order (R-RCTP-30)."""
        if field_value is None:
            return None
        out: list[Node] = []
        for raw in field_value.split(","):
            segs = wire.decode_target("/" + raw.strip(" \t"))
            if not segs or len(segs) != 1 or not is_xml_name(segs[0]):
                return None
            node = access.children.get(segs[0])
            if node is None or node.kind != "data":
                return None
            ahead = out and out[-1].name.encode() >= node.name.encode()
            if "nodes-repeat-accepted" in self.faults:  # off by one: a repeat passes
                ahead = out and out[-1].name.encode() > node.name.encode()
            if ahead:
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
            if bugs.on("session-timeout-crash"):
                try:  # the bug: refreshes a second, from half the timeout in whole seconds
                    _rate = 1 / (self.timeout // 2)
                except ZeroDivisionError as exc:
                    bugs.crash(exc)
            self.state = "open"

        target = "/" if "connect-to-root" in self.faults else self.url.path
        msg = await self.call("CONNECT", target, on_ok=opened)
        if msg.status == 200 and self.state == "open":
            self.log(f"session {self.sid}, timeout {self.timeout} s")
            return True
        self.log(f"CONNECT {self.url.path}: {msg.status} {msg.reason}", always=True)
        return False

    async def bye(self) -> None:
        """BYE, then close once it is answered (or after 5 s without an answer)."""
        if self.closed or self.state != "open":
            return
        with contextlib.suppress(Closed):
            await self.call("BYE", "*")
        if "request-after-bye" in self.faults:
            with contextlib.suppress(Closed):
                await self.call("RELEASE", "*")
        if "bye-not-closed" in self.faults:
            await self._close_after(30.0, "the server kept the connection open")
        self.close("BYE")

    async def _refresh(self) -> None:
        with contextlib.suppress(Closed):
            await self.call("CONNECT", self.url.path)

    # ---- event and stream accesses ----------------------------------------------------------

    def _to_init(self, acc: Access) -> None:
        acc.state = "init"
        _cancel(acc.beater)
        acc.beater = None
        if "data-after-stop" not in self.faults:
            _cancel(acc.sender)
            acc.sender = None

    def _start_sender(self, acc: Access) -> None:
        if acc.stream and acc.writes and acc.sender is None and not self.closed:
            acc.sender = asyncio.get_running_loop().create_task(self._sender(acc))

    async def setup(self, node: Node, mode: str = "") -> Access | None:
        acc = self.accesses.setdefault(node.path, Access(node))
        acc.stopped, acc.usable = False, True
        fields = []
        if node.atype == "stream":
            if self.udp is None:
                await self._open_udp()
            fields = [("Transport", f"udp;client_port={self.udp_port};mode={mode}")]

        def ready(msg: Message) -> None:
            acc.state = "ready"
            if node.atype != "stream":
                return
            if not self._transport(acc, mode, msg.get("Transport")):
                self.log(f"SETUP {node.path}: unusable Transport {msg.get('Transport')!r}", True)
                acc.usable = False
            elif "data-at-setup" in self.faults:
                self._start_sender(acc)

        msg = await self.call("SETUP", node.path, fields, on_ok=ready)
        return acc if msg.status == 200 and acc.usable else None

    def _transport(self, acc: Access, mode: str, value: str | None) -> bool:
        """The answer's Transport, its tokens in any letter case (D-RCTP-30)."""
        parts = (value or "").split(";")
        if parts[0].strip().lower() != "udp":
            return False
        params: dict[str, str] = {}
        for part in parts[1:]:
            key, _, val = part.strip().partition("=")
            params[key.lower()] = val
        try:
            port, sid = int(params["server_port"]), int(params["stream"])
            if not re.fullmatch(r"[0-9A-Fa-f]{8}", params["tag"]) or not 1 <= port <= 65535:
                return False
            if not 1 <= sid <= 255:
                return False
        except (KeyError, ValueError):
            return False
        answered = params.get("mode", mode).lower()
        if answered not in ("read", "write", "both"):
            return False
        self.tag, self.server_port = int(params["tag"], 16), port
        first = acc.stream_id == 0
        acc.stream_id, acc.mode = sid, answered
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
            if not acc.stream:
                return
            self._start_sender(acc)  # DATA at once, then every write interval
            if acc.beater is None and "no-heartbeats" not in self.faults:
                acc.beater = asyncio.get_running_loop().create_task(self._beater())

        return (await self.call("GO", acc.node.path, on_ok=playing)).status == 200

    async def pause(self, acc: Access) -> None:
        def paused(_msg: Message) -> None:
            acc.state = "ready"
            _cancel(acc.beater)
            acc.beater = None
            if "data-after-pause" not in self.faults:
                _cancel(acc.sender)
                acc.sender = None

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

    def _send_packet(self, payloads: list[tuple[int, int, bytes]], flow: bool = False) -> None:
        if self.udp is None or self.tag is None or self.closed:
            return
        if flow and "seq-separate-flow-counter" in self.faults:
            seq, self.flow_seq = self.flow_seq, (self.flow_seq + 1) % 65536
        else:
            seq, self.seq = self.seq, (self.seq + 1) % 65536
        packet = ds.build_packet(
            seq,
            self.tag,
            ds.ntp_now("packet-timestamp-unix" in self.faults),
            payloads,
            version=1 if "packet-version-1" in self.faults else ds.VERSION,
            tag_le="tag-little-endian" in self.faults,
        )
        self.udp.sendto(packet, (self.server_ip, self.server_port))
        self.last_sent = time.monotonic()

    def _payload(self, acc: Access) -> bytes:
        """D-RCTP-31 step 6: each writable node gets the newest value applied of the readable
        node of the same name, else its zero value (D-RCTP-20: canonical order)."""
        nodes = list(acc.writes)
        if "stream-document-order" in self.faults:
            nodes.sort(key=lambda n: n.doc_index)
        values = [acc.values.get(n.name, zero(n)) for n in nodes]
        return self.codec.encode(nodes, values)

    async def _sender(self, acc: Access) -> None:
        """DATA of a writing stream once per write interval while it plays (R-RCTP-44)."""
        loop = asyncio.get_running_loop()
        due = loop.time()
        while not self.closed:
            self._send_packet([(ds.DATA, acc.stream_id, self._payload(acc))])
            every = acc.write_interval
            if "data-at-read-interval" in self.faults and acc.read_interval:
                every = acc.read_interval
            interval = max(every, 1000) / 1e6
            due += interval
            now = loop.time()
            if due < now - interval:
                due = now
            await asyncio.sleep(max(0.0, due - now))

    async def _beater(self) -> None:
        """A heartbeat at once, then every second, while the stream plays (D-RCTP-31)."""
        while not self.closed:
            rid = self.rid
            self.rid = (self.rid + 1) % 65536
            body = ds.flow_body(ds.REQUEST, ds.HEARTBEAT, rid, struct.pack("!Q", ds.ntp_now()))
            self.flow[rid] = FlowRequest(0, ds.HEARTBEAT, body, due=time.monotonic() + FLOW_RETRY)
            self._send_packet([(ds.FLOW, 0, body)], flow=True)
            await asyncio.sleep(HEARTBEAT_EVERY)

    def on_datagram(self, data: bytes, addr: Any) -> None:
        t2 = ds.ntp_now("heartbeat-unix-epoch" in self.faults)
        if self.tag is None or self.closed:
            return
        checks = "tag-not-checked" not in self.faults
        if checks and (addr[0] != self.server_ip or addr[1] != self.server_port):
            return
        packet = ds.parse_packet(data)
        if packet is None or (checks and packet.tag != self.tag):
            return  # dropped unread (R-RCTP-42)
        newer = self.order.newer(packet.seq)
        if bugs.on("late-packet-leak") and not newer:
            for ptype, sid, _body in packet.payloads:
                acc = self._by_stream(sid)
                if ptype == ds.DATA and acc is not None and acc.state == "playing":
                    bugs.leak(data)  # the bug: a late packet waits for a reorder never done
                    break
        answers = []
        for ptype, sid, body in packet.payloads:
            if ptype == ds.FLOW and len(body) < 4 and "broken-flow-ends-packet" in self.faults:
                break  # the fault: a broken FLOW body ends the packet's reading
            if ptype == ds.DATA and (newer or "apply-stale-packets" in self.faults):
                self._on_data(sid, body)
            elif ptype == ds.FLOW:
                answer = self._on_flow(sid, body, t2)
                if answer is not None:
                    answers.append(answer)
        if answers:
            self._send_packet(answers, flow=True)

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
            ranged = "data-range-unchecked" not in self.faults
            values = self.codec.decode(acc.reads, body, ranged)
        except BadValue:
            if "data-partial-apply" in self.faults:  # the values before the bad one are taken
                prefix: list[Any] = []
                with contextlib.suppress(BadValue):
                    self.codec.decode_prefix(acc.reads, body, prefix, ranged)
                acc.values.update((n.name, v) for n, v in zip(acc.reads, prefix, strict=False))
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
        if "flow-ack-wrong-id" in self.faults:
            rid = self.rid
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
            theirs = (op == ds.SET_INTERVAL) == reading
            if theirs and not (op == ds.SET_INTERVAL and "set-interval-read-acked" in self.faults):
                return ds.nack(op, rid, ds.NOT_PERMITTED)
            if op == ds.SET_INTERVAL and reading:
                acc.read_interval = value  # the fault set-interval-read-acked
            elif op == ds.SET_INTERVAL:
                if value < ds.micros(acc.node.timing.get("writeInterval", 0.0)):
                    return ds.nack(op, rid, ds.REFUSED)
                if bugs.on("flow-top-bit-hang") and value >= 2**31 and acc.state == "playing":
                    bugs.hang()  # the bug: the sender's catch-up takes the interval as signed
                if "write-interval-not-applied" not in self.faults:
                    acc.write_interval = value
            else:
                times = 1 if "timeout-min-one-interval" in self.faults else 2
                if value < times * acc.read_interval:
                    return ds.nack(op, rid, ds.REFUSED)
                if bugs.on("flow-top-bit-hang") and value >= 2**31 and acc.state == "playing":
                    bugs.hang()  # the bug: the loss watch takes the timeout as signed
                acc.read_timeout = value
        if "flow-ack-no-direction" in self.faults:
            return ds.flow_body(ds.ACK, op, rid, struct.pack("!I", value))
        return ds.flow_body(ds.ACK, op, rid, struct.pack("!BI", direction, value))

    def _on_flow_answer(self, message: int, op: int, rid: int, fields: bytes) -> None:
        request = self.flow.get(rid)
        if request is None or request.op != op:
            return
        if message == ds.NACK:
            if len(fields) != 1:
                return
            self.log(f"FLOW request {rid} (operation {op}) refused: NACK {fields[0]}")
        elif op == ds.HEARTBEAT:
            if len(fields) != 24 or fields[:8] != request.body[4:12]:
                return
            t4 = time.time()
            t1, t2, t3 = struct.unpack("!QQQ", fields)
            if bugs.on("heartbeat-ack-crash") and t3 < t2:
                try:  # the bug: the server's hold time goes into a jitter estimate unchecked
                    math.sqrt(t3 - t2)
                except ValueError as exc:
                    bugs.crash(exc)
            self.clock.add(ds.ntp_to_unix(t1), ds.ntp_to_unix(t2), ds.ntp_to_unix(t3), t4)
        elif len(fields) != 5:
            return
        del self.flow[rid]

    async def _housekeeping(self) -> None:
        """Retransmit FLOW requests, watch receive timeouts, keep the session alive."""
        while not self.closed:
            await asyncio.sleep(0.05)
            now = time.monotonic()
            for rid, request in list(self.flow.items()):
                if now < request.due:
                    continue
                if request.sends >= FLOW_SENDS:  # D-RCTP-22: five sends, then no answer
                    del self.flow[rid]
                    continue
                request.sends += 1
                request.due = now + FLOW_RETRY
                self._send_packet([(ds.FLOW, request.sid, request.body)], flow=True)
            for acc in self.accesses.values():
                if not (acc.stream and acc.state == "playing" and acc.reads and not acc.lost):
                    continue
                if now - acc.last_data > acc.read_timeout / 1e6:
                    acc.lost = True  # D-RCTP-23: reported; the server will STOP it
                    self.log(f"stream {acc.node.path}: nothing for its read timeout", always=True)
            if self.state == "open" and now - self.last_sent >= self.timeout / 2:
                self.last_sent = now
                self._spawn(self._refresh())


def _cancel(task: asyncio.Task[Any] | None) -> None:
    if task is not None:
        task.cancel()
