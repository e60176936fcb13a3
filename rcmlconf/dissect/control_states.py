"""What the receiver of an RCTP/2.0 request must answer on its own, and what answers change.

The states are the core's (`rctp.states`: the session's, D-RCTP-13, and each access's stream,
D-RCTP-14), judged in the order of `Connection._check_request` (D-RCTP-25): a request is judged in
the states its sender's earlier requests' answers left, and the answer that came is compared with
the one due.
"""

from __future__ import annotations

from rcmlconf.dissect.context import Findings
from rcmlconf.dissect.control_sides import CLIENT, SERVER, Sent
from rcmlconf.dissect.records import Severity
from rcmlconf.errors import ValueTextError
from rcmlconf.rctp.connection import SINGLE_FIELDS
from rcmlconf.rctp.fields import SessionField, parse_session
from rcmlconf.rctp.messages import METHODS, SERVER_METHODS, VERSION, Response
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


class ControlStates:
    """The states of one control connection, as both its ends must see them."""

    def __init__(self, findings: Findings) -> None:
        self.findings = findings
        self.session_state = SessionState.IDLE
        self.session: SessionField | None = None
        self.streams: dict[str, StreamState] = {}
        #: The requests their receiver had to refuse on its own: (message number, status due or
        #: None for dropped unanswered, rule).
        self.refused: list[tuple[int, int | None, str]] = []

    def event(self, event: SessionEvent) -> None:
        after = SESSION_TRANSITIONS.get((self.session_state, event))
        if after is not None:
            self.session_state = after

    # -- requests --------------------------------------------------------------------------------

    def check(self, role: str | None, sent: Sent) -> None:
        """Judge a request of the `role` as its receiver does (D-RCTP-25), in the states its
        earlier requests' answers left (D-RCTP-13, D-RCTP-14)."""
        sent.checked = True
        request = sent.request
        due = self._due(role, sent)
        if due is None:
            return
        sent.due = due
        status, why, rule = due
        self.refused.append((sent.number, status, rule))
        answer = f"answered {status}" if status is not None else "dropped unanswered"
        if status is None or status in (454, 455):
            severity = Severity.WARNING
            text = (
                f"{request.method} {request.target} from the {role} (CSeq {sent.cseq}):"
                f" not allowed: {why}; its receiver must see it {answer}"
            )
        else:
            # Sent by the peer, these break a MUST of the sender's (R-RCTP-2, -3, -15, ...)
            # and are reported where they were read; here only what the answer must be.
            severity = Severity.NOTE
            text = (
                f"{request.method} {request.target} from the {role} (CSeq {sent.cseq}):"
                f" {why}; due: {answer}"
            )
        self.findings.add(severity, rule, text, sent.frame, sent.time, sent.number)

    def _due(self, role: str | None, sent: Sent) -> tuple[int | None, str, str] | None:
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
        if role == SERVER and method not in SERVER_METHODS:
            return 405, f"a server does not send {method}", "R-RCTP-25"
        try:
            path = parse_target(request.target).path
        except ValueTextError as exc:
            return 400, f"target: {exc}", "R-RCTP-15"
        if state is SessionState.CLOSING:
            return 455, "the session is ending (BYE)", "R-RCTP-20"
        given = request.headers.get("Session")
        if state is SessionState.IDLE:
            if method == "CONNECT" and role == CLIENT:
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
        if role == SERVER and method == "WRITE" and stream not in PUSH_STATES:
            return 455, f"a data-change WRITE of an access in state {stream.value}", "R-RCTP-20"
        if method == "BYE" and path == "*":
            self.event(SessionEvent.BYE)
        return None

    # -- answers ---------------------------------------------------------------------------------

    def judge_answer(
        self, role: str | None, sent: Sent, response: Response, number: int, frame: int, time: float
    ) -> None:
        """The answer of the `role` to a request it had to refuse, against the status due."""
        if sent.due is None:
            return
        status, why, rule = sent.due
        request = sent.request
        if status is None:
            return
        if 200 <= response.status < 300:
            self.findings.add(
                Severity.ERROR,
                rule,
                f"the {role} answered {request.method} {request.target} (CSeq {sent.cseq})"
                f" {response.status}; due: {status} ({why})",
                frame,
                time,
                number,
            )
        elif response.status != status:
            self.findings.add(
                Severity.WARNING,
                "R-RCTP-20" if status in (454, 455) else rule,
                f"the {role} answered {request.method} {request.target} (CSeq {sent.cseq})"
                f" {response.status}; D-RCTP-25 gives {status} ({why})",
                frame,
                time,
                number,
            )

    def apply(
        self, sent: Sent, response: Response, number: int, frame: int, time: float
    ) -> str | None:
        """What an answered request changes (D-RCTP-13, D-RCTP-14): the access path of a stream
        method answered 200, else None."""
        method = sent.request.method
        status = response.status
        findings = self.findings
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
                self.event(SessionEvent.CONNECT_ACCEPTED)
            else:
                self.event(SessionEvent.CONNECT_REFUSED)
            return None
        if method == "BYE":
            if self.session_state is SessionState.CLOSING:
                self.event(SessionEvent.BYE_ANSWERED)
            return None
        self.event(SessionEvent.ANSWERED)
        if method not in STREAM_METHODS or status != 200:
            return None
        try:
            path = parse_target(sent.request.target).path
        except ValueTextError:
            return None
        after = STREAM_TRANSITIONS.get((self.streams.get(path, StreamState.INIT), method))
        if after is not None:
            if after is StreamState.INIT:
                self.streams.pop(path, None)
            else:
                self.streams[path] = after
        return path
