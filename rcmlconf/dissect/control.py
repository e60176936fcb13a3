"""RCTP/2.0 control connections seen from the wire: both directions, and what the states allow.

Each direction's bytes are put in order by `tcp.TcpStream` and framed by the core's
`MessageReader` (Content-Length, pipelining, the limits of D-RCTP-9; its `RemoteProtocolError`
gives the offset and rule of a message that cannot be framed). The connection is watched as the
core's `Connection` would judge it from either end, with the same tables (`rctp.states`:
D-RCTP-13 and D-RCTP-14) and the same order of checks (D-RCTP-25): a request is judged when its
receiver would judge it — once every earlier request of its sender is answered, so that a GO
pipelined after its SETUP sees the state the SETUP's answer left — and the answer that came is
compared with the one due (`control_states`). A response carries an `Answer` and the values
(`control_bodies`) in its record (`control_results`); SETUP's answer names the data stream
(`control_setup`).
"""

from __future__ import annotations

import bisect
import statistics

from rcmlconf.dissect.context import Context
from rcmlconf.dissect.control_bodies import body_values
from rcmlconf.dissect.control_results import Answer, BodyValues, ControlReport, Exchange
from rcmlconf.dissect.control_setup import learn_data_stream
from rcmlconf.dissect.control_sides import CLIENT, SERVER, Sent, Side
from rcmlconf.dissect.control_states import ControlStates
from rcmlconf.dissect.records import RCTP, Endpoints, Malformed, Severity, make_record
from rcmlconf.dissect.tcp import ACK, SYN
from rcmlconf.errors import ValueTextError
from rcmlconf.rctp.errors import RemoteProtocolError
from rcmlconf.rctp.fields import parse_cseq
from rcmlconf.rctp.messages import SERVER_METHODS, VERSION, Message, Request, Response
from rcmlconf.rctp.states import SessionEvent

#: The method of a request that could not be framed, in the analysis.
UNFRAMED = "(unframed)"
#: The requirement that says what a request that cannot be framed is answered.
_ANSWER_RULE = {413: "R-RCTP-16", 414: "R-RCTP-16", 431: "R-RCTP-16"}


class ControlConnection:
    def __init__(
        self,
        ctx: Context,
        first: Side,
        second: Side,
        server_ports: frozenset[int],
    ) -> None:
        self.ctx = ctx
        self.sides = (first, second)
        self.server_ports = server_ports
        self.states = ControlStates(ctx.findings)
        self.exchanges: list[Exchange] = []
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
        one = Side(Endpoints(source[2], destination[2], RCTP), source[0], source[1])
        two = Side(Endpoints(destination[2], source[2], RCTP), destination[0], destination[1])
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
            self.states.event(SessionEvent.CLOSED)  # D-RCTP-13: the connection closes
        if not pieces or side.dead:
            return
        for offset, data, at_frame, at_time, located in pieces:
            side.pieces.append((offset, at_frame, at_time, located))
            side.reader.feed(data)
            self._read(side, frame, time)
            if side.dead:
                return

    def _hole(self, side: Side, frame: int, time: float) -> None:
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
        """The capture is over: holes never filled, requests never answered (but those whose
        answers would come after a hole the capture has: they cannot be told)."""
        for side in self.sides:
            if side.tcp.waiting and not side.dead:
                side.tcp.give_up()
                self._hole(side, side.pieces[-1][1] if side.pieces else 0, self.last_time)
        for side, answering in zip(self.sides, reversed(self.sides), strict=True):
            if answering.tcp.holes:
                continue
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

    def _read(self, side: Side, frame: int, time: float) -> None:
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

    def _locate(self, side: Side, offset: int) -> tuple[int, float, int | None]:
        """The frame, time and file offset of a byte of the side's stream."""
        pieces = side.pieces
        index = bisect.bisect_right(pieces, (offset, 1 << 62)) - 1
        if index < 0:
            return 0, 0.0, None
        start, frame, time, located = pieces[index]
        return frame, time, (located + offset - start) if located >= 0 else None

    def _malformed(self, side: Side, error: RemoteProtocolError, frame: int, time: float) -> None:
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
            sent = Sent(Request(UNFRAMED, "-"), None, ctx.count, frame, time)
            sent.checked = True
            sent.due = (error.status, error.reason, _ANSWER_RULE.get(error.status, "R-RCTP-8"))
            side.pending.append(sent)

    def _message(self, side: Side, message: Message, offset: int, frame: int, time: float) -> None:
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
                values = body_values(
                    ctx.options.rcml, message.target, message.headers.get("Nodes"), message.body
                )
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
                    values = body_values(ctx.options.rcml, request.target, nodes, message.body)
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

    # -- roles ---------------------------------------------------------------------------------

    def _roles(self, index: int, role: str) -> None:
        self.sides[index].role = role
        self.sides[1 - index].role = SERVER if role == CLIENT else CLIENT

    def _guess_roles(self, side: Side, other: Side, message: Message) -> None:
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
        self, side: Side, request: Request, cseq: int | None, number: int, frame: int, time: float
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
        sent = Sent(request, cseq, number, frame, time)
        sent.expected = out_of_sequence
        side.pending.append(sent)
        if len(side.pending) == 1:
            self.states.check(side.role, sent)

    # -- responses -------------------------------------------------------------------------------

    def _response(
        self,
        side: Side,
        requester: Side,
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
            if match is None and sent.request.method == UNFRAMED and sent.cseq is None:
                pass  # D-RCTP-10: its receiver may have read a CSeq the capture cannot tell
            elif match is None:
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
            self.states.check(requester.role, sent)
        self.states.judge_answer(side.role, sent, response, number, frame, time)
        if sent.due is None:  # refused on its own, it changes nothing: nor ends closing (D-RCTP-13)
            path = self.states.apply(sent, response, number, frame, time)
            if path is not None and sent.request.method == "SETUP":
                self._setup(requester, sent.request, response, path, (number, frame, time))
        if requester.pending and not requester.pending[0].checked:
            self.states.check(requester.role, requester.pending[0])
        return Answer(sent.request, elapsed, sent.number)

    def _setup(
        self,
        client: Side,
        request: Request,
        response: Response,
        path: str,
        where: tuple[int, int, float],
    ) -> None:
        """The 200 to the `client`'s SETUP of `path` names the data stream (D-RCTP-18)."""
        server = self.sides[1] if client is self.sides[0] else self.sides[0]
        session = self.states.session
        session_id = session.id if session is not None else None
        addresses = (client.address, server.address)
        learn_data_stream(self.ctx, addresses, session_id, request, response, path, where)

    # -- the analysis ----------------------------------------------------------------------------

    def report(self) -> ControlReport:
        client, server = self.sides
        if client.role == SERVER:
            client, server = server, client
        states = self.states
        session = states.session
        times: dict[str, list[float]] = {}
        for exchange in self.exchanges:
            times.setdefault(exchange.method, []).append(exchange.elapsed)
        return ControlReport(
            client.endpoints.source,
            server.endpoints.source,
            session.id if session is not None else None,
            session.timeout if session is not None else None,
            states.session_state.value,
            client.requests + server.requests,
            client.responses + server.responses,
            client.malformed + server.malformed,
            {
                method: (len(values), min(values), statistics.median(values), max(values))
                for method, values in sorted(times.items())
            },
            {path: state.value for path, state in sorted(states.streams.items())},
            tuple(sorted(states.refused)),
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
