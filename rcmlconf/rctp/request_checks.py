"""What the receiver of a request answers on its own: D-RCTP-25's first checks, in its order.

Method (501), version (505), `CSeq` and repeated fields (400), the direction (405, D-RCTP-12),
the target's syntax (400), the session (454) and the session's and streams' states (455,
D-RCTP-13, D-RCTP-14) need no knowledge of the robot, so the protocol makes them itself: the
core's `Connection` answers a request that fails one, and the dissector says what a request's
receiver had to answer. Both ask `first_refusal`, so that they cannot judge a request apart.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Protocol

from rcmlconf.errors import ValueTextError
from rcmlconf.rctp.fields import SessionField, parse_cseq, parse_session
from rcmlconf.rctp.messages import METHODS, SERVER_METHODS, VERSION, Message, Request
from rcmlconf.rctp.states import (
    PUSH_STATES,
    STREAM_METHODS,
    STREAM_TRANSITIONS,
    Role,
    SessionState,
    StreamState,
)
from rcmlconf.rctp.targets import parse_target

#: The fields a message holds at most once (§2.2): a request repeating one is answered 400
#: (R-RCTP-11). Content-Length is the reader's business. The Wireshark plugin flags them too.
SINGLE_FIELDS = ("CSeq", "Session", "Content-Type", "Nodes", "Transport")
#: D-RCTP-12, D-RCTP-15: a client's 405 to a method only clients send lists what a server sends.
_SERVER_SENDS = "WRITE, STOP, BYE"
#: The order check's rule: R-RCTP-4 binds the sender; a receiver may check it (D-RCTP-6).
ORDER_RULE = "R-RCTP-4"
_CLOSED = "the session is over (D-RCTP-13: nothing is sent in closed)"


@dataclass(frozen=True, slots=True)
class Refusal:
    """The answer a request's receiver gives on its own, and why."""

    #: None for a request it drops unanswered: nothing is sent in closed (D-RCTP-13).
    status: int | None
    #: For people: the answer's text/plain body (D-RCTP-8).
    reason: str
    rule: str
    #: A 405's `Allow` (D-RCTP-15).
    allow: str | None = None


class Agreed(Protocol):
    """What the two ends of a control connection share: the session (D-RCTP-13) and the states
    of its accesses (D-RCTP-14, absent: init)."""

    @property
    def session_state(self) -> SessionState: ...

    #: None when not known (a capture whose answer to CONNECT names no readable session).
    @property
    def session(self) -> SessionField | None: ...

    @property
    def streams(self) -> Mapping[str, StreamState]: ...


def request_cseq(message: Message) -> int | None:
    """The message's `CSeq` (a request's, or the one a response echoes), or None without one
    single valid field (R-RCTP-3, R-RCTP-11)."""
    try:
        return _cseq(message)
    except ValueTextError:
        return None


def first_refusal(
    request: Request, receiver: Role, expected: int | None, agreed: Agreed
) -> Refusal | None:
    """The first of the protocol's own checks (D-RCTP-25) that the `receiver` finds `request`
    fails, in the states `agreed` holds; None when it passes them all. `expected` is the CSeq
    next in order (D-RCTP-6: one more than the last readable), None when not known."""
    if agreed.session_state is SessionState.CLOSED:
        return Refusal(None, _CLOSED, "R-RCTP-23")
    method = request.method
    if method not in METHODS:
        return Refusal(501, f"{method} is not an RCTP/2.0 method", "R-RCTP-9")
    if request.version != VERSION:
        return Refusal(505, f"{request.version} is not RCTP/2.0", "R-RCTP-10")
    try:
        cseq = _cseq(request)
    except ValueTextError as exc:
        return Refusal(400, str(exc), "R-RCTP-11")
    names = [name.lower() for name, _ in request.headers]
    for name in SINGLE_FIELDS:
        if names.count(name.lower()) > 1:
            return Refusal(400, f"{name} appears more than once", "R-RCTP-11")
    if expected is not None and cseq != expected:
        return Refusal(400, f"CSeq {cseq}, where {expected} was next", ORDER_RULE)
    if receiver is Role.CLIENT and method not in SERVER_METHODS:
        return Refusal(405, f"a server does not send {method}", "R-RCTP-25", _SERVER_SENDS)
    try:
        path = parse_target(request.target).path
    except ValueTextError as exc:
        return Refusal(400, f"target: {exc}", "R-RCTP-15")
    return _session_refusal(request, receiver, agreed) or _stream_refusal(
        method, path, receiver, agreed
    )


def _cseq(message: Message) -> int:
    texts = message.headers.get_all("CSeq")
    if len(texts) != 1:
        raise ValueTextError("the request has no single CSeq")
    return parse_cseq(texts[0])


def _session_refusal(request: Request, receiver: Role, agreed: Agreed) -> Refusal | None:
    """454 and 455 of D-RCTP-13 and R-RCTP-17, -19; None when the session allows the request."""
    state = agreed.session_state
    if state is SessionState.CLOSING:
        return Refusal(455, "the session is ending (BYE)", "R-RCTP-20")
    given = request.headers.get("Session")
    if state is SessionState.IDLE:
        if request.method == "CONNECT" and receiver is Role.SERVER:
            return None
        return Refusal(454, "no session yet: CONNECT first", "R-RCTP-17")
    if given is None:
        if request.method == "CONNECT":
            return Refusal(455, "this connection has a session already", "R-RCTP-20")
        return Refusal(454, "the request does not name the session", "R-RCTP-19")
    session = agreed.session
    if session is None:
        return None  # a session not known cannot be told from another
    try:
        named = parse_session(given).id
    except ValueTextError:
        named = None
    if named != session.id:
        return Refusal(454, "the request names another session", "R-RCTP-19")
    return None


def _stream_refusal(method: str, path: str, receiver: Role, agreed: Agreed) -> Refusal | None:
    """455 of D-RCTP-14, and of a client for a data-change WRITE of an access not playing on its
    side (D-RCTP-26, D-RCTP-27); None when the access's state allows the request."""
    # R-RCTP-20 binds a server; R-RCTP-68 is its answer from the client.
    rule = "R-RCTP-20" if receiver is Role.SERVER else "R-RCTP-68"
    state = agreed.streams.get(path, StreamState.INIT)
    if method in STREAM_METHODS and (state, method) not in STREAM_TRANSITIONS:
        return Refusal(455, f"{method} of a stream in state {state.value}", rule)
    if receiver is Role.CLIENT and method == "WRITE" and state not in PUSH_STATES:
        return Refusal(455, f"a data-change WRITE of an access in state {state.value}", rule)
    return None
