"""RCTP/2.0 control connections seen from the wire: both directions, and what the states allow.

Each direction's bytes are put in order by `tcp.TcpStream` and framed by the core's
`MessageReader` (Content-Length, pipelining, the limits of D-RCTP-9; its `RemoteProtocolError`
gives the offset and rule of a message that cannot be framed). The connection is watched as the
core's `Connection` would judge it from either end, with the same tables (`rctp.states`:
D-RCTP-13 and D-RCTP-14) and the same order of checks (D-RCTP-25): a request is judged when its
receiver would judge it — once every earlier request of its sender is answered, so that a GO
pipelined after its SETUP sees the state the SETUP's answer left — and the answer that came is
compared with the one due.
"""

from __future__ import annotations

import bisect
import statistics
from collections import deque
from dataclasses import dataclass

from rcmlconf.dissect.context import Context, DataSession
from rcmlconf.dissect.records import (
    RCTP,
    Endpoints,
    Malformed,
    Severity,
    make_record,
)
from rcmlconf.dissect.tcp import ACK, SYN, TcpStream
from rcmlconf.errors import ProtocolError, ValueTextError
from rcmlconf.rcml.model import AccessNode, DataNode
from rcmlconf.rctp.bodies import ValuesCodec
from rcmlconf.rctp.connection import SINGLE_FIELDS
from rcmlconf.rctp.errors import RemoteProtocolError
from rcmlconf.rctp.fields import (
    SessionField,
    parse_cseq,
    parse_nodes,
    parse_session,
    parse_transport,
)
from rcmlconf.rctp.messages import METHODS, SERVER_METHODS, VERSION, Message, Request, Response
from rcmlconf.rctp.reader import MessageReader
from rcmlconf.rctp.states import (
    PUSH_STATES,
    SESSION_TRANSITIONS,
    STREAM_METHODS,
    STREAM_TRANSITIONS,
    SessionEvent,
    SessionState,
    StreamState,
)
from rcmlconf.rctp.targets import parse_target
from rcmlconf.values import Value

#: The method of a request that could not be framed, in the analysis.
UNFRAMED = "(unframed)"
CLIENT = "client"
SERVER = "server"
#: The requirement that says what a request that cannot be framed is answered.
_ANSWER_RULE = {413: "R-RCTP-16", 414: "R-RCTP-16", 431: "R-RCTP-16"}


@dataclass(frozen=True, slots=True)
class Answer:
    """`Record.extra` of a response: the request it answers, and how long that took."""

    request: Request
    #: Seconds from the request's last byte to the response's, as the capture saw them.
    elapsed: float
    #: The request's record number.
    message: int
    #: The values of a READ's answer, decoded with the RCML (D-RCTP-8), by node name.
    values: dict[str, Value] | None = None


@dataclass(frozen=True, slots=True)
class BodyValues:
    """`Record.extra` of a WRITE whose body the RCML decodes: its values, by node name."""

    values: dict[str, Value]


@dataclass(frozen=True, slots=True)
class Exchange:
    method: str
    #: Who sent the request.
    by: str
    elapsed: float


@dataclass(frozen=True, slots=True)
class ControlReport:
    """One control connection, for the analysis."""

    client: str
    server: str
    session: str | None
    timeout: int | None
    state: str
    requests: int
    responses: int
    malformed: int
    #: method -> (count, min, median, max) seconds of its request-to-response times.
    response_times: dict[str, tuple[int, float, float, float]]
    #: Access path -> its stream state at the end (D-RCTP-14).
    streams: dict[str, str]
    #: The requests their receiver had to refuse on its own (D-RCTP-25, D-RCTP-13, D-RCTP-14):
    #: (message number, status due or None for dropped unanswered, rule), in message order.
    refused: tuple[tuple[int, int | None, str], ...]
    #: Segments that repeated bytes already seen, segments ahead of a hole, and holes the
    #: capture never filled (bytes lost to the capture).
    retransmissions: int
    out_of_order: int
    holes: int
    first: float
    last: float


class _Sent:
    """A request, until it is answered."""

    __slots__ = ("checked", "cseq", "due", "expected", "frame", "number", "request", "time")

    def __init__(self, request: Request, cseq: int | None, number: int, frame: int, time: float):
        self.request = request
        self.cseq = cseq
        self.number = number
        self.frame = frame
        self.time = time
        self.checked = False
        #: The CSeq that was next when this one came instead (R-RCTP-4), or None.
        self.expected: int | None = None
        #: (status due, why, rule) when the request's receiver must refuse it; status None for
        #: a request that is dropped unanswered (after the session closed).
        self.due: tuple[int | None, str, str] | None = None


class _Side:
    """One direction: what one end sent."""

    __slots__ = (
        "address",
        "dead",
        "endpoints",
        "malformed",
        "next_cseq",
        "pending",
        "pieces",
        "port",
        "reader",
        "requests",
        "responses",
        "role",
        "tcp",
    )

    def __init__(self, endpoints: Endpoints, address: bytes, port: int) -> None:
        self.endpoints = endpoints
        self.address = address
        self.port = port
        self.role: str | None = None
        self.tcp = TcpStream()
        self.reader = MessageReader()
        #: Framing is lost (a message that cannot be framed, or a hole in the capture).
        self.dead = False
        #: (stream offset, frame, time, file offset of that byte or -1), one per piece fed.
        self.pieces: list[tuple[int, int, float, int]] = []
        self.next_cseq: int | None = None
        #: This side's requests not yet answered, oldest first.
        self.pending: deque[_Sent] = deque()
        self.requests = 0
        self.responses = 0
        self.malformed = 0


class ControlConnection:
    def __init__(
        self,
        ctx: Context,
        first: _Side,
        second: _Side,
        server_ports: frozenset[int],
    ) -> None:
        self.ctx = ctx
        self.sides = (first, second)
        self.server_ports = server_ports
        self.session_state = SessionState.IDLE
        self.session: SessionField | None = None
        self.streams: dict[str, StreamState] = {}
        self.exchanges: list[Exchange] = []
        self.refused: list[tuple[int, int | None, str]] = []
        #: The Transport of each SETUP request, for its answer.
        self.first_time: float | None = None
        self.last_time = 0.0

    @classmethod
    def open(
        cls,
        ctx: Context,
        source: tuple[bytes, int, str],
        destination: tuple[bytes, int, str],
        server_ports: frozenset[int],
    ) -> ControlConnection:
        """`source` sent the first segment seen: (address, port, endpoint text)."""
        one = _Side(Endpoints(source[2], destination[2], RCTP), source[0], source[1])
        two = _Side(Endpoints(destination[2], source[2], RCTP), destination[0], destination[1])
        return cls(ctx, one, two, server_ports)

    # -- segments --------------------------------------------------------------------------------

    def segment(
        self,
        index: int,
        time: float,
        frame: int,
        sequence: int,
        flags: int,
        payload: bytes,
        where: int,
    ) -> None:
        """A segment from side `index` (0: the side that sent the first segment seen)."""
        side = self.sides[index]
        if self.first_time is None:
            self.first_time = time
        self.last_time = time
        if side.role is None and flags & SYN:
            self._roles(index, SERVER if flags & ACK else CLIENT)
        tcp = side.tcp
        holes = tcp.holes
        pieces = tcp.segment(sequence, flags, payload, frame, time, where)
        if tcp.holes != holes:
            self._hole(side, frame, time)
        if tcp.finished:
            self._session_event(SessionEvent.CLOSED)  # D-RCTP-13: the connection closes
        if not pieces or side.dead:
            return
        for offset, data, at_frame, at_time, located in pieces:
            side.pieces.append((offset, at_frame, at_time, located))
            side.reader.feed(data)
            self._read(side, frame, time)
            if side.dead:
                return

    def _hole(self, side: _Side, frame: int, time: float) -> None:
        self.ctx.findings.add(
            Severity.NOTE,
            "R-RCTP-13",
            f"{side.endpoints.source} → {side.endpoints.destination}: the capture lost"
            f" {side.tcp.skipped} bytes of the stream; what follows is not decoded",
            frame,
            time,
        )
        side.dead = True

    def end(self) -> None:
        """The capture is over: holes never filled, requests never answered."""
        for side in self.sides:
            if side.tcp.waiting and not side.dead:
                side.tcp.give_up()
                self._hole(side, side.pieces[-1][1] if side.pieces else 0, self.last_time)
        for side in self.sides:
            for sent in side.pending:
                if sent.due is not None and sent.due[0] is None:
                    continue  # dropped unanswered, as D-RCTP-13 wants
                self.ctx.findings.add(
                    Severity.WARNING,
                    "R-RCTP-5",
                    f"{sent.request.method} {sent.request.target} (CSeq {sent.cseq}) from"
                    f" {side.endpoints.source} was never answered in the capture",
                    sent.frame,
                    sent.time,
                    sent.number,
                )

    # -- messages --------------------------------------------------------------------------------

    def _read(self, side: _Side, frame: int, time: float) -> None:
        reader = side.reader
        while True:
            offset = reader.offset
            try:
                message = reader.next_message()
            except RemoteProtocolError as error:
                self._malformed(side, error, frame, time)
                return
            if message is None:
                return
            self._message(side, message, offset, frame, time)

    def _locate(self, side: _Side, offset: int) -> tuple[int, float, int | None]:
        """The frame, time and file offset of a byte of the side's stream."""
        pieces = side.pieces
        index = bisect.bisect_right(pieces, (offset, 1 << 62)) - 1
        if index < 0:
            return 0, 0.0, None
        start, frame, time, located = pieces[index]
        return frame, time, (located + offset - start) if located >= 0 else None

    def _malformed(self, side: _Side, error: RemoteProtocolError, frame: int, time: float) -> None:
        side.dead = True
        side.malformed += 1
        ctx = self.ctx
        ctx.count += 1
        ctx.by_protocol[RCTP] += 1
        at_frame, _, file_offset = self._locate(side, error.offset)
        # A request that cannot be framed is answered 400 (R-RCTP-8); a response that cannot be
        # framed closes the connection (R-RCTP-12). The reader names a finer rule when it can.
        rule = error.rule or ("R-RCTP-8" if error.answerable else "R-RCTP-12")
        malformed = Malformed(error.reason, error.offset, rule, file_offset)
        record = make_record(
            ctx.count, frame, time, side.endpoints, "malformed", None, None, malformed
        )
        ctx.findings.add(
            Severity.ERROR,
            rule,
            f"{side.endpoints.source} → {side.endpoints.destination}: a message that cannot be"
            f" framed at stream byte {error.offset}: {error.reason}; the rest of this direction"
            " is not decoded (D-RCTP-10)",
            at_frame or frame,
            time,
            ctx.count,
            file_offset,
        )
        ctx.emit(record)
        if error.answerable:
            # D-RCTP-10: a request that cannot be framed is still answered, with its status.
            sent = _Sent(Request(UNFRAMED, "-"), None, ctx.count, frame, time)
            sent.checked = True
            sent.due = (error.status, error.reason, _ANSWER_RULE.get(error.status, "R-RCTP-8"))
            side.pending.append(sent)

    def _message(self, side: _Side, message: Message, offset: int, frame: int, time: float) -> None:
        ctx = self.ctx
        ctx.count += 1
        ctx.by_protocol[RCTP] += 1
        number = ctx.count
        other = self.sides[1] if side is self.sides[0] else self.sides[0]
        if side.role is None:
            self._guess_roles(side, other, message)
        cseq = _cseq(message.headers.get_all("CSeq"))
        if isinstance(message, Request):
            side.requests += 1
            values = None
            if message.body and message.method == "WRITE":
                values = self._values(message.target, message.headers.get("Nodes"), message.body)
            record = make_record(
                number,
                frame,
                time,
                side.endpoints,
                message.method,
                cseq,
                message,
                None,
                BodyValues(values) if values is not None else None,
            )
            ctx.emit(record)
            self._request(side, message, cseq, number, frame, time)
        else:
            side.responses += 1
            answer = self._response(side, other, message, cseq, number, frame, time)
            if answer is not None and message.body and message.status == 200:
                request = answer.request
                if request.method == "READ":
                    nodes = message.headers.get("Nodes") or request.headers.get("Nodes")
                    values = self._values(request.target, nodes, message.body)
                    if values is not None:
                        answer = Answer(request, answer.elapsed, answer.message, values)
            record = make_record(
                number,
                frame,
                time,
                side.endpoints,
                f"{message.status} {message.reason}",
                cseq,
                message,
                None,
                answer,
            )
            ctx.emit(record)

    def _values(self, target: str, nodes: str | None, body: bytes) -> dict[str, Value] | None:
        """A body's values (D-RCTP-8): of the data node the target names, or of the `Nodes` of
        the event access it names (D-RCTP-17); None without the RCML, or when they do not
        decode (the answer to that is the server's: 422, R-RCTP-28)."""
        rcml = self.ctx.options.rcml
        if rcml is None:
            return None
        try:
            path = parse_target(target).path
        except ValueTextError:
            return None
        node = rcml.node(path)
        if isinstance(node, DataNode):
            chosen: tuple[DataNode, ...] = (node,)
        elif isinstance(node, AccessNode) and nodes is not None:
            by_name = {data.name: data for data in node.data}
            try:
                names = parse_nodes(nodes)
            except ValueTextError:
                return None
            if not all(name in by_name for name in names):
                return None
            chosen = tuple(by_name[name] for name in names)
        else:
            return None
        try:
            return ValuesCodec(chosen, path, "R-RCTP-28").decode(body)
        except ProtocolError:
            return None

    # -- roles ---------------------------------------------------------------------------------

    def _roles(self, index: int, role: str) -> None:
        self.sides[index].role = role
        self.sides[1 - index].role = SERVER if role == CLIENT else CLIENT

    def _guess_roles(self, side: _Side, other: _Side, message: Message) -> None:
        """No handshake seen: the server is the end on a known RCTP port, else the end that
        answers or sends only what servers send."""
        index = 0 if side is self.sides[0] else 1
        if other.port in self.server_ports and side.port not in self.server_ports:
            self._roles(index, CLIENT)
        elif side.port in self.server_ports and other.port not in self.server_ports:
            self._roles(index, SERVER)
        elif isinstance(message, Response) or message.method in SERVER_METHODS:
            self._roles(index, SERVER if isinstance(message, Response) else CLIENT)
        else:
            self._roles(index, CLIENT)

    # -- requests --------------------------------------------------------------------------------

    def _request(
        self, side: _Side, request: Request, cseq: int | None, number: int, frame: int, time: float
    ) -> None:
        findings = self.ctx.findings
        where = f"{request.method} {request.target} from the {side.role}"
        out_of_sequence = None
        if request.version != VERSION:
            findings.add(
                Severity.ERROR,
                "R-RCTP-2",
                f"{where}: version {request.version}",
                frame,
                time,
                number,
            )
        if cseq is None:
            texts = request.headers.get_all("CSeq")
            problem = "no CSeq" if not texts else f"CSeq {', '.join(texts)[:30]!r}"
            findings.add(Severity.ERROR, "R-RCTP-3", f"{where}: {problem}", frame, time, number)
        else:
            expected = side.next_cseq
            if expected is not None and cseq != expected:
                out_of_sequence = expected
                findings.add(
                    Severity.ERROR,
                    "R-RCTP-4",
                    f"{where}: CSeq {cseq}, where {expected} was next",
                    frame,
                    time,
                    number,
                )
            elif expected is None and cseq != 1 and side.tcp.from_start and not side.tcp.holes:
                out_of_sequence = 1
                findings.add(
                    Severity.ERROR,
                    "R-RCTP-4",
                    f"{where}: CSeq {cseq} for the first request of the connection, not 1",
                    frame,
                    time,
                    number,
                )
            side.next_cseq = cseq + 1
        if side.role == SERVER and request.method not in SERVER_METHODS:
            findings.add(
                Severity.ERROR,
                "R-RCTP-25",
                f"{where}: a server does not send {request.method} (D-RCTP-12)",
                frame,
                time,
                number,
            )
        sent = _Sent(request, cseq, number, frame, time)
        sent.expected = out_of_sequence
        side.pending.append(sent)
        if len(side.pending) == 1:
            self._check(side, sent)

    def _check(self, side: _Side, sent: _Sent) -> None:
        """Judge a request as its receiver does (D-RCTP-25), in the states its earlier requests'
        answers left (D-RCTP-13, D-RCTP-14)."""
        sent.checked = True
        request = sent.request
        due = self._due(side, sent)
        if due is None:
            return
        sent.due = due
        status, why, rule = due
        self.refused.append((sent.number, status, rule))
        answer = f"answered {status}" if status is not None else "dropped unanswered"
        if status is None or status in (454, 455):
            severity = Severity.WARNING
            text = (
                f"{request.method} {request.target} from the {side.role} (CSeq {sent.cseq}):"
                f" not allowed: {why}; its receiver must see it {answer}"
            )
        else:
            # Sent by the peer, these break a MUST of the sender's (R-RCTP-2, -3, -15, ...)
            # and are reported where they were read; here only what the answer must be.
            severity = Severity.NOTE
            text = (
                f"{request.method} {request.target} from the {side.role} (CSeq {sent.cseq}):"
                f" {why}; due: {answer}"
            )
        self.ctx.findings.add(severity, rule, text, sent.frame, sent.time, sent.number)

    def _due(self, side: _Side, sent: _Sent) -> tuple[int | None, str, str] | None:
        """What the receiver of a request must answer on its own, per D-RCTP-25's first checks
        and the states (`Connection._check_request`'s order); None when the request passes."""
        request = sent.request
        cseq = sent.cseq
        method = request.method
        state = self.session_state
        if state is SessionState.CLOSED:
            return None, "the session is over (D-RCTP-13: nothing is sent in closed)", "R-RCTP-23"
        if method not in METHODS:
            return 501, f"{method} is not an RCTP/2.0 method", "R-RCTP-9"
        if request.version != VERSION:
            return 505, f"{request.version} is not RCTP/2.0", "R-RCTP-10"
        if cseq is None:
            return 400, "no valid CSeq", "R-RCTP-11"
        names = [name.lower() for name, _ in request.headers]
        for name in SINGLE_FIELDS:
            if names.count(name.lower()) > 1:
                return 400, f"{name} appears more than once", "R-RCTP-11"
        if sent.expected is not None:
            return 400, f"CSeq {cseq}, where {sent.expected} was next", "R-RCTP-4"
        if side.role == SERVER and method not in SERVER_METHODS:
            return 405, f"a server does not send {method}", "R-RCTP-25"
        try:
            path = parse_target(request.target).path
        except ValueTextError as exc:
            return 400, f"target: {exc}", "R-RCTP-15"
        if state is SessionState.CLOSING:
            return 455, "the session is ending (BYE)", "R-RCTP-20"
        given = request.headers.get("Session")
        if state is SessionState.IDLE:
            if method == "CONNECT" and side.role == CLIENT:
                return None
            return 454, "no session yet: CONNECT first", "R-RCTP-17"
        session = self.session
        if given is None:
            if method == "CONNECT":
                return 455, "this connection has a session already", "R-RCTP-20"
            return 454, "the request does not name the session", "R-RCTP-19"
        try:
            named = parse_session(given).id
        except ValueTextError:
            named = None
        if session is not None and named != session.id:
            return 454, "the request names another session", "R-RCTP-19"
        stream = self.streams.get(path, StreamState.INIT)
        if method in STREAM_METHODS and (stream, method) not in STREAM_TRANSITIONS:
            return 455, f"{method} of a stream in state {stream.value} (D-RCTP-14)", "R-RCTP-20"
        if side.role == SERVER and method == "WRITE" and stream not in PUSH_STATES:
            return 455, f"a data-change WRITE of an access in state {stream.value}", "R-RCTP-20"
        if method == "BYE" and path == "*":
            self._session_event(SessionEvent.BYE)
        return None

    # -- responses -------------------------------------------------------------------------------

    def _response(
        self,
        side: _Side,
        requester: _Side,
        response: Response,
        cseq: int | None,
        number: int,
        frame: int,
        time: float,
    ) -> Answer | None:
        findings = self.ctx.findings
        where = f"{response.status} from the {side.role} (CSeq {cseq})"
        if not requester.pending:
            findings.add(
                Severity.ERROR,
                "R-RCTP-12",
                f"{where}: answers no request (D-RCTP-6)",
                frame,
                time,
                number,
            )
            return None
        sent = requester.pending[0]
        if cseq != sent.cseq:
            match = next(
                (s for s in requester.pending if s.cseq == cseq and cseq is not None), None
            )
            if match is None:
                findings.add(
                    Severity.ERROR,
                    "R-RCTP-3",
                    f"{where}: the oldest request waiting, {sent.request.method}, is CSeq"
                    f" {sent.cseq} (D-RCTP-6)",
                    frame,
                    time,
                    number,
                )
            else:
                findings.add(
                    Severity.ERROR,
                    "R-RCTP-5",
                    f"{where}: answers {match.request.method} before the older"
                    f" {sent.request.method} (CSeq {sent.cseq})",
                    frame,
                    time,
                    number,
                )
                sent = match
        requester.pending.remove(sent)
        elapsed = time - sent.time
        if sent.request.method != UNFRAMED:
            self.exchanges.append(Exchange(sent.request.method, requester.role or "?", elapsed))
        if not sent.checked:
            self._check(requester, sent)
        self._judge_answer(side, sent, response, number, frame, time)
        if sent.due is None or sent.request.method == "BYE":
            self._apply(requester, sent, response, number, frame, time)
        if requester.pending and not requester.pending[0].checked:
            self._check(requester, requester.pending[0])
        return Answer(sent.request, elapsed, sent.number)

    def _judge_answer(
        self, side: _Side, sent: _Sent, response: Response, number: int, frame: int, time: float
    ) -> None:
        if sent.due is None:
            return
        status, why, rule = sent.due
        request = sent.request
        if status is None:
            return
        if 200 <= response.status < 300:
            self.ctx.findings.add(
                Severity.ERROR,
                rule,
                f"the {side.role} answered {request.method} {request.target} (CSeq {sent.cseq})"
                f" {response.status}; due: {status} ({why})",
                frame,
                time,
                number,
            )
        elif response.status != status:
            self.ctx.findings.add(
                Severity.WARNING,
                "R-RCTP-20" if status in (454, 455) else rule,
                f"the {side.role} answered {request.method} {request.target} (CSeq {sent.cseq})"
                f" {response.status}; D-RCTP-25 gives {status} ({why})",
                frame,
                time,
                number,
            )

    def _apply(
        self,
        requester: _Side,
        sent: _Sent,
        response: Response,
        number: int,
        frame: int,
        time: float,
    ) -> None:
        """What an answered request changes (D-RCTP-13, D-RCTP-14)."""
        method = sent.request.method
        status = response.status
        findings = self.ctx.findings
        if method == "CONNECT":
            if status == 200:
                given = response.headers.get("Session")
                try:
                    session = parse_session(given or "")
                except ValueTextError as exc:
                    findings.add(
                        Severity.ERROR, "R-RCTP-18", f"CONNECT's 200: {exc}", frame, time, number
                    )
                    session = None
                if session is not None and session.timeout is None:
                    findings.add(
                        Severity.ERROR,
                        "R-RCTP-18",
                        "CONNECT's 200 gives no timeout in its Session",
                        frame,
                        time,
                        number,
                    )
                if session is not None:
                    self.session = session
                self._session_event(SessionEvent.CONNECT_ACCEPTED)
            else:
                self._session_event(SessionEvent.CONNECT_REFUSED)
            return
        if method == "BYE":
            if self.session_state is SessionState.CLOSING:
                self._session_event(SessionEvent.BYE_ANSWERED)
            return
        self._session_event(SessionEvent.ANSWERED)
        if method not in STREAM_METHODS or status != 200:
            return
        try:
            path = parse_target(sent.request.target).path
        except ValueTextError:
            return
        after = STREAM_TRANSITIONS.get((self.streams.get(path, StreamState.INIT), method))
        if after is not None:
            if after is StreamState.INIT:
                self.streams.pop(path, None)
            else:
                self.streams[path] = after
        if method == "SETUP":
            self._setup(requester, sent, response, path, number, frame, time)

    def _setup(
        self,
        requester: _Side,
        sent: _Sent,
        response: Response,
        path: str,
        number: int,
        frame: int,
        time: float,
    ) -> None:
        """D-RCTP-18, D-RCTP-28: the answer to SETUP of a stream access names the data stream."""
        asked = sent.request.headers.get("Transport")
        if asked is None:
            return  # an event access
        findings = self.ctx.findings
        text = response.headers.get("Transport")
        try:
            request_transport = parse_transport(asked)
            transport = parse_transport(text) if text is not None else None
        except ValueTextError as exc:
            findings.add(
                Severity.ERROR, "R-RCTP-38", f"SETUP {path}'s 200: {exc}", frame, time, number
            )
            return
        if transport is None or None in (transport.server_port, transport.tag, transport.stream):
            findings.add(
                Severity.ERROR,
                "R-RCTP-38",
                f"SETUP {path}'s 200 does not give the Transport's server_port, tag and stream",
                frame,
                time,
                number,
            )
            if transport is None or transport.tag is None:
                return
        client = requester
        server = self.sides[1] if requester is self.sides[0] else self.sides[0]
        tag = transport.tag
        assert tag is not None
        ctx = self.ctx
        session = ctx.data_sessions.get(tag)
        client_port = transport.client_port or request_transport.client_port
        if session is None:
            rcml = ctx.options.rcml
            session = DataSession(
                tag,
                client.address,
                server.address,
                transport.server_port,
                client_port,
                self.session.id if self.session is not None else None,
                precision=(rcml.time_precision or 0.0) if rcml is not None else 0.0,
            )
        else:
            session.client_port = client_port
            if transport.server_port is not None:
                session.server_port = transport.server_port
        if transport.stream is not None:
            session.streams[transport.stream] = (path, transport)
        ctx.learn(session)

    def _session_event(self, event: SessionEvent) -> None:
        after = SESSION_TRANSITIONS.get((self.session_state, event))
        if after is not None:
            self.session_state = after

    # -- the analysis ----------------------------------------------------------------------------

    def report(self) -> ControlReport:
        client, server = self.sides
        if client.role == SERVER:
            client, server = server, client
        times: dict[str, list[float]] = {}
        for exchange in self.exchanges:
            times.setdefault(exchange.method, []).append(exchange.elapsed)
        return ControlReport(
            client.endpoints.source,
            server.endpoints.source,
            self.session.id if self.session is not None else None,
            self.session.timeout if self.session is not None else None,
            self.session_state.value,
            client.requests + server.requests,
            client.responses + server.responses,
            client.malformed + server.malformed,
            {
                method: (len(values), min(values), statistics.median(values), max(values))
                for method, values in sorted(times.items())
            },
            {path: state.value for path, state in sorted(self.streams.items())},
            tuple(sorted(self.refused)),
            client.tcp.retransmissions + server.tcp.retransmissions,
            client.tcp.out_of_order + server.tcp.out_of_order,
            client.tcp.holes + server.tcp.holes,
            self.first_time or 0.0,
            self.last_time,
        )


def _cseq(texts: list[str]) -> int | None:
    if len(texts) != 1:
        return None
    try:
        return parse_cseq(texts[0])
    except ValueTextError:
        return None
