"""What the receiver of an RCTP/2.0 request must answer on its own, and what answers change.

The states are the core's (`rctp.states`: the session's, D-RCTP-13, and each access's stream,
D-RCTP-14), and so are the checks: a request is judged by `rctp.request_checks` (D-RCTP-25), as
the core's `Connection` judges it, in the states its sender's earlier requests' answers left, and
the answer that came is compared with the one due.
"""

from __future__ import annotations

from rcmlconf.dissect.context import Findings
from rcmlconf.dissect.control_sides import CLIENT, Sent
from rcmlconf.dissect.records import Severity
from rcmlconf.errors import ValueTextError
from rcmlconf.rctp.fields import SessionField, parse_session
from rcmlconf.rctp.messages import Response
from rcmlconf.rctp.request_checks import ORDER_RULE, Refusal, first_refusal
from rcmlconf.rctp.states import (
    SESSION_TRANSITIONS,
    STREAM_METHODS,
    STREAM_TRANSITIONS,
    Role,
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
        status, why, rule = due.status, due.reason, due.rule
        sent.due = (status, why, rule)
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

    def _due(self, role: str | None, sent: Sent) -> Refusal | None:
        """What the receiver of a request of the `role` must answer on its own: the core's own
        checks (D-RCTP-25) in the states the earlier answers left; None when it passes them."""
        # ControlConnection gives both sides their roles before it reads a message.
        assert role is not None
        receiver = Role.SERVER if role == CLIENT else Role.CLIENT
        # `sent.expected` is None where the CSeq came in order, or the order is not known.
        request = sent.request
        due = first_refusal(request, receiver, sent.expected, self)
        if due is None and request.method == "BYE" and parse_target(request.target).is_session:
            self.event(SessionEvent.BYE)  # D-RCTP-13: a valid BYE received
        return due

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
        if rule == ORDER_RULE:
            return  # D-RCTP-6: a receiver need not check the order; one that does answers 400
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
                rule,
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
