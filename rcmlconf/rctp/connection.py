"""One RCTP/2.0 control connection, either role, without I/O (specs/rctp-2.0.md §2, §3).

Bytes and a `now` go in (`receive_data`), events come out (`next_event`), bytes to send collect
in `data_to_send()`, and time is a value (`get_timer()`, `handle_timer(now)`), as in aioquic.

Requests flow both ways (D-RCTP-5), each side numbering its own (D-RCTP-6). The connection makes
the first checks of D-RCTP-25 itself — framing (its reader), then `request_checks`: method,
version, CSeq, direction, target syntax, session and states — and answers a request that fails
one with its status, in order, without troubling the application; the application sees only
requests that pass, and answers them with `send_response`. Responses leave in the order their
requests arrived (R-RCTP-5), whoever wrote them. As an HTTP/1.1 server takes pipelined requests
(and h11 hands them over), the application has one received request at a time: the next is
checked, and handed over, once the one before it is answered, so that its checks see the states
the earlier answers left.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterable
from dataclasses import dataclass

from rcmlconf.errors import ValueTextError
from rcmlconf.rctp.errors import LocalProtocolError, RemoteProtocolError
from rcmlconf.rctp.fields import (
    SessionField,
    parse_cseq,
    parse_session,
)
from rcmlconf.rctp.messages import (
    REASONS,
    SERVER_METHODS,
    VALUES_TYPE,
    Headers,
    Request,
    Response,
)
from rcmlconf.rctp.reader import LIMITS, Limits, MessageReader
from rcmlconf.rctp.request_checks import Refusal, first_refusal, request_cseq
from rcmlconf.rctp.states import (
    SESSION_TRANSITIONS,
    STREAM_METHODS,
    STREAM_TRANSITIONS,
    Role,
    SessionEvent,
    SessionState,
    StreamState,
)
from rcmlconf.rctp.targets import Target, parse_target
from rcmlconf.rctp.writer import write_message

#: R-RCTP-23: how long the sender of BYE waits for its answer before closing.
BYE_WAIT = 5.0


# -- events ------------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class RequestReceived:
    """A request that passed the protocol's own checks: the application answers it."""

    request: Request
    cseq: int
    target: Target


@dataclass(frozen=True, slots=True)
class ResponseReceived:
    """The answer to a request this side sent."""

    response: Response
    request: Request


@dataclass(frozen=True, slots=True)
class RequestRejected:
    """A request the connection answered on its own with an error status (D-RCTP-25)."""

    request: Request
    status: int
    reason: str
    rule: str | None


@dataclass(frozen=True, slots=True)
class ProtocolFailure:
    """The peer broke framing or transactions: close once data_to_send() is sent (D-RCTP-10)."""

    error: RemoteProtocolError


@dataclass(frozen=True, slots=True)
class SessionOpened:
    session: SessionField


@dataclass(frozen=True, slots=True)
class SessionEnded:
    """The BYE exchange is over (or its answer never came): close the connection."""

    by: Role
    reason: str | None


@dataclass(frozen=True, slots=True)
class SessionTimedOut:
    """Server: no request or data-stream packet for the session's timeout; BYE is on its way."""


@dataclass(frozen=True, slots=True)
class KeepAliveDue:
    """Client: half the session's timeout has passed without a request; refresh (D-RCTP-11)."""


@dataclass(frozen=True, slots=True)
class ConnectionClosed:
    """The peer closed the connection."""


Event = (
    RequestReceived
    | ResponseReceived
    | RequestRejected
    | ProtocolFailure
    | SessionOpened
    | SessionEnded
    | SessionTimedOut
    | KeepAliveDue
    | ConnectionClosed
)


@dataclass(slots=True)
class _Inbound:
    """A received request, waiting for its answer to be written (in order, R-RCTP-5).

    `request` is None for a message too broken to be read as one (D-RCTP-10).
    """

    request: Request | None
    cseq: int | None
    answer: bytes | None = None
    #: Handed to the application as `RequestReceived`, which owes its answer.
    handed: bool = False


class Connection:
    def __init__(
        self,
        role: Role,
        now: float,
        limits: Limits = LIMITS,
        session_timeout: float | None = None,
    ) -> None:
        self.role = role
        self.session_state = SessionState.IDLE
        self.session: SessionField | None = None
        #: Per access path: the stream's state (D-RCTP-14); absent means init.
        self.streams: dict[str, StreamState] = {}
        self._reader = MessageReader(limits)
        self._events: deque[Event] = deque()
        self._out = bytearray()
        self._next_cseq = 1
        self._expected_cseq = 1
        self._sent: deque[Request] = deque()
        self._inbound: deque[_Inbound] = deque()
        #: Received requests not yet checked: they wait for the application's answers before
        #: them. `_with_application` counts requests it has and has not answered.
        self._deferred: deque[_Inbound] = deque()
        self._with_application = 0
        self._checking = False
        self._failed = False
        self._eof = False
        self._last_activity = now
        #: Overrides the timeout of the Session field (tests, and servers that know better).
        self._session_timeout = session_timeout
        self._bye_deadline: float | None = None

    # -- input -------------------------------------------------------------------------------

    def receive_data(self, data: bytes, now: float) -> None:
        """Bytes from the peer; b"" when it closed the connection."""
        if not data:
            if not self._eof:
                self._eof = True
                self._session_event(SessionEvent.CLOSED)
                self._events.append(ConnectionClosed())
            return
        if self._failed or self.session_state is SessionState.CLOSED:
            return
        self._reader.feed(data)
        self._read_messages(now)

    def _read_messages(self, now: float) -> None:
        while not self._failed:
            offset = self._reader.offset
            try:
                message = self._reader.next_message()
            except RemoteProtocolError as error:
                self._fail(error)
                return
            if message is None:
                return
            if isinstance(message, Request):
                if self.role is Role.SERVER:
                    self._last_activity = now
                self._receive_request(message, offset)
            else:
                self._receive_response(message, offset, now)

    def note_activity(self, now: float) -> None:
        """A data-stream packet of this session arrived: it keeps the session alive (D-RCTP-11)."""
        self._last_activity = now

    @property
    def buffered(self) -> int:
        """Bytes received that are not yet a whole message (a server times them, D-RCTP-32)."""
        return self._reader.buffered

    @property
    def peer(self) -> Role:
        return Role.SERVER if self.role is Role.CLIENT else Role.CLIENT

    @property
    def answers_due(self) -> int:
        """Received requests whose answers are not yet written."""
        return sum(1 for inbound in self._inbound if inbound.answer is None)

    @property
    def requests_unanswered(self) -> tuple[Request, ...]:
        """This side's requests still waiting for their answers, oldest first."""
        return tuple(self._sent)

    def next_event(self) -> Event | None:
        return self._events.popleft() if self._events else None

    def data_to_send(self) -> bytes:
        data = bytes(self._out)
        self._out.clear()
        return data

    # -- requests received -------------------------------------------------------------------

    def _receive_request(self, request: Request, offset: int) -> None:
        """A request takes its place in the answering order at once, and is checked once every
        request before it is answered: a pipelined GO is judged in the state its SETUP's answer
        left (R-RCTP-13), as an HTTP server takes pipelined requests one after the other."""
        inbound = _Inbound(request, None)
        self._inbound.append(inbound)
        self._deferred.append(inbound)
        self._check_deferred()

    def _check_deferred(self) -> None:
        if self._checking:
            return  # a check that answers on its own comes back here: the loop below goes on
        self._checking = True
        try:
            while self._deferred and not self._with_application:
                self._check_request(self._deferred.popleft())
        finally:
            self._checking = False

    def _check_request(self, inbound: _Inbound) -> None:
        """D-RCTP-25: the protocol's own checks, in order; the first that fails answers."""
        request = inbound.request
        assert request is not None  # a slot for a broken message is never deferred
        # The CSeq is read first, so that every answer that can echo it does (R-RCTP-3).
        # Numbering follows every readable CSeq, whatever else is wrong with the request, so
        # that one bad request does not put every later one out of sequence.
        inbound.cseq = cseq = request_cseq(request)
        expected = self._expected_cseq
        if cseq is not None:
            self._expected_cseq = cseq + 1
        refusal = first_refusal(request, self.role, expected, self)
        if refusal is not None:
            return self._refuse(inbound, refusal)
        assert cseq is not None  # a request without one is refused
        target = parse_target(request.target)
        if request.method == "BYE" and target.is_session:
            # R-RCTP-23: a valid BYE is answered 200, by the connection. A BYE of a node is the
            # application's to answer (405, D-RCTP-26), as it alone knows the node's kind.
            self._session_event(SessionEvent.BYE)
            self.send_response(request, 200)
            return None
        inbound.handed = True
        self._with_application += 1
        self._events.append(RequestReceived(request, cseq, target))
        return None

    def _refuse(self, inbound: _Inbound, refusal: Refusal) -> None:
        """Answer a request that failed a check with its status, or drop it (D-RCTP-13)."""
        request = inbound.request
        assert request is not None  # only a request that could be read is rejected
        if refusal.status is None:
            # D-RCTP-13: nothing is sent in closed. A request pipelined after BYE is checked
            # once the BYE is answered, and is dropped unanswered and unapplied.
            self._inbound.remove(inbound)
            return
        headers = [("Allow", refusal.allow)] if refusal.allow else []
        body = refusal.reason.encode("utf-8")
        inbound.answer = self._answer_bytes(inbound.cseq, refusal.status, headers, body, text=True)
        self._events.append(RequestRejected(request, refusal.status, refusal.reason, refusal.rule))
        self._flush_answers()

    # -- responses received ------------------------------------------------------------------

    def _receive_response(self, response: Response, offset: int, now: float) -> None:
        """D-RCTP-6: a response answers this side's oldest unanswered request, by CSeq."""
        cseq_text = response.headers.get("CSeq")
        if not self._sent:
            return self._response_broken(
                "a response, but no request is waiting for one", offset, "R-RCTP-12"
            )
        request = self._sent[0]
        try:
            cseq = parse_cseq(cseq_text) if cseq_text is not None else None
        except ValueTextError:
            cseq = None
        expected = int(request.headers.get("CSeq") or 0)
        if cseq != expected:
            return self._response_broken(
                f"response CSeq {cseq_text!r}, where {expected} is the oldest unanswered",
                offset,
                "R-RCTP-12",
            )
        if request.method == "CONNECT" and response.status == 200:
            try:
                parse_session(response.headers.get("Session") or "")
            except ValueTextError as exc:
                # No session to go on with: the connection is of no more use (D-RCTP-10).
                return self._response_broken(
                    f"the answer to CONNECT names no session: {exc}", offset, "R-RCTP-18"
                )
        self._sent.popleft()
        self._events.append(ResponseReceived(response, request))
        self._exchange_done(request, response.status, response.headers, ours=True)
        return None

    def _response_broken(self, reason: str, offset: int, rule: str) -> None:
        """A response this side cannot go on after: framing or the session is lost, and a
        response is never answered (D-RCTP-10)."""
        self._fail(RemoteProtocolError(reason, offset, 400, rule, fatal=True, answerable=False))

    # -- sending -----------------------------------------------------------------------------

    def send_request(
        self,
        method: str,
        target: str,
        headers: Iterable[tuple[str, str]] = (),
        body: bytes = b"",
        *,
        now: float,
    ) -> Request:
        """Queue a request; CSeq, Session and Content-Length are added. Returns it as sent."""
        if self.session_state is SessionState.CLOSED or self._failed:
            raise LocalProtocolError("the connection is closed")
        if self.role is Role.SERVER and method not in SERVER_METHODS:
            raise LocalProtocolError(f"a server does not send {method} (D-RCTP-12)")
        fields = self._with_session([("CSeq", str(self._next_cseq)), *headers])
        request = Request(method, target, Headers.of(self._body_fields(fields, body)), body)
        self._out += write_message(request)
        self._next_cseq += 1
        self._sent.append(request)
        if self.role is Role.CLIENT:
            self._last_activity = now  # what keeps a session alive is what the client says
        if method == "BYE":
            self._session_event(SessionEvent.BYE)
            self._bye_deadline = now + BYE_WAIT
        return request

    def send_response(
        self,
        request: Request,
        status: int,
        headers: Iterable[tuple[str, str]] = (),
        body: bytes = b"",
        reason: str | None = None,
    ) -> None:
        """Answer a received request; it leaves once every earlier request is answered."""
        inbound = next(
            (i for i in self._inbound if i.request is request and i.answer is None), None
        )
        if inbound is None:
            raise LocalProtocolError("no such request waits for an answer")
        fields = list(headers)
        if request.method == "CONNECT" and status == 200:
            given = next((v for n, v in fields if n.lower() == "session"), None)
            if given is None:
                raise LocalProtocolError("the answer to CONNECT names the session (R-RCTP-18)")
            session = parse_session(given)
            if session.timeout is None:
                raise LocalProtocolError("the answer to CONNECT gives the timeout (R-RCTP-18)")
        inbound.answer = self._answer_bytes(inbound.cseq, status, fields, body, reason=reason)
        if inbound.handed:
            self._with_application -= 1
        self._exchange_done(request, status, Headers.of(fields), ours=False)
        self._flush_answers()
        self._check_deferred()

    def _answer_bytes(
        self,
        cseq: int | None,
        status: int,
        headers: list[tuple[str, str]],
        body: bytes,
        reason: str | None = None,
        text: bool = False,
    ) -> bytes:
        fields = [("CSeq", str(cseq))] if cseq is not None else []
        fields = self._with_session([*fields, *headers])
        if text and body and not any(n.lower() == "content-type" for n, _ in fields):
            fields.append(("Content-Type", "text/plain; charset=utf-8"))
        phrase = reason if reason is not None else REASONS.get(status, "Unknown")
        return write_message(
            Response(status, phrase, Headers.of(self._body_fields(fields, body)), body)
        )

    def _with_session(self, fields: list[tuple[str, str]]) -> list[tuple[str, str]]:
        """The fields, and the session's `Session` unless they name it (R-RCTP-19)."""
        if self.session is not None and not any(n.lower() == "session" for n, _ in fields):
            fields.append(("Session", self.session.id))
        return fields

    @staticmethod
    def _body_fields(fields: list[tuple[str, str]], body: bytes) -> list[tuple[str, str]]:
        """Content-Length (and the default Content-Type) of a body (R-RCTP-6)."""
        if not body:
            return fields
        names = {name.lower() for name, _ in fields}
        if "content-length" not in names:
            fields.append(("Content-Length", str(len(body))))
        if "content-type" not in names:
            fields.append(("Content-Type", VALUES_TYPE))
        return fields

    def _flush_answers(self) -> None:
        """R-RCTP-5: answers leave in the order their requests arrived."""
        while self._inbound:
            answer = self._inbound[0].answer
            if answer is None:
                return
            self._out += answer
            self._inbound.popleft()

    # -- what an exchange changes ------------------------------------------------------------

    def _exchange_done(self, request: Request, status: int, headers: Headers, ours: bool) -> None:
        """What an answered request changes; `ours` when this side sent the request."""
        method = request.method
        if method == "CONNECT":
            if status == 200:
                session = parse_session(headers.get("Session") or "")
                opened = self.session is None
                self.session = session
                self._session_event(SessionEvent.CONNECT_ACCEPTED)
                if opened:
                    self._events.append(SessionOpened(session))
            else:
                self._session_event(SessionEvent.CONNECT_REFUSED)
        elif method == "BYE":
            if self.session_state is SessionState.CLOSING:
                self._end_session(self.role if ours else self.peer, request.headers.get("Reason"))
        else:
            self._session_event(SessionEvent.ANSWERED)
            if method in STREAM_METHODS and status == 200:
                path = parse_target(request.target).path
                after = STREAM_TRANSITIONS.get((self._stream_state(path), method))
                if after is not None:
                    self._set_stream(path, after)

    def _stream_state(self, path: str) -> StreamState:
        return self.streams.get(path, StreamState.INIT)

    def _set_stream(self, path: str, state: StreamState) -> None:
        if state is StreamState.INIT:
            self.streams.pop(path, None)
        else:
            self.streams[path] = state

    def _session_event(self, event: SessionEvent) -> None:
        after = SESSION_TRANSITIONS.get((self.session_state, event))
        if after is not None:
            self.session_state = after

    def _end_session(self, by: Role, reason: str | None) -> None:
        self._session_event(SessionEvent.BYE_ANSWERED)
        self._bye_deadline = None
        self._events.append(SessionEnded(by, reason))

    def _fail(self, error: RemoteProtocolError) -> None:
        """D-RCTP-10: answer a broken request (after the requests before it), read no more.

        The caller closes the connection once `data_to_send()` is empty and `answers_due` is 0.
        """
        self._failed = True
        if error.answerable:
            answer = self._answer_bytes(
                None, error.status, [], error.reason.encode("utf-8"), text=True
            )
            self._inbound.append(_Inbound(None, None, answer))
            self._flush_answers()
        self._events.append(ProtocolFailure(error))

    # -- timers ------------------------------------------------------------------------------

    @property
    def timeout(self) -> float | None:
        if self._session_timeout is not None:
            return self._session_timeout
        if self.session is not None and self.session.timeout is not None:
            return float(self.session.timeout)
        return None

    def get_timer(self) -> float | None:
        """When handle_timer should next be called, or None."""
        if self._bye_deadline is not None:
            return self._bye_deadline  # the session is closing: nothing else is due
        timeout = self.timeout
        if self.session_state is SessionState.OPEN and timeout is not None:
            share = 1.0 if self.role is Role.SERVER else 0.5
            return self._last_activity + timeout * share
        return None

    def handle_timer(self, now: float) -> None:
        if self._bye_deadline is not None and now >= self._bye_deadline:
            self._session_event(SessionEvent.BYE_ANSWERED)
            self._bye_deadline = None
            self._events.append(SessionEnded(self.role, "no answer to BYE"))
            return
        timeout = self.timeout
        if self.session_state is not SessionState.OPEN or timeout is None:
            return
        if self.role is Role.SERVER and now >= self._last_activity + timeout:
            self._events.append(SessionTimedOut())
            self.send_request("BYE", "*", [("Reason", "timeout")], now=now)  # R-RCTP-21
        elif self.role is Role.CLIENT and now >= self._last_activity + timeout / 2:
            self._last_activity = now
            self._events.append(KeepAliveDue())
