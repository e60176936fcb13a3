"""The protocol's own checks of a request (D-RCTP-25), as the core's connection and the dissector
both make them: which fails first, from either role, in each session and stream state."""

from __future__ import annotations

from dataclasses import dataclass, field

import pytest

from rcmlconf.rctp.fields import SessionField
from rcmlconf.rctp.messages import Headers, Request
from rcmlconf.rctp.request_checks import Refusal, first_refusal, request_cseq
from rcmlconf.rctp.states import Role, SessionState, StreamState

OURS = "abcdefgh1234"


@dataclass
class Agreed:
    session_state: SessionState = SessionState.OPEN
    session: SessionField | None = field(default_factory=lambda: SessionField(OURS))
    streams: dict[str, StreamState] = field(default_factory=dict)


def request(
    method: str = "READ",
    target: str = "/a",
    cseq: tuple[str, ...] = ("2",),
    session: str | None = OURS,
    version: str = "RCTP/2.0",
    extra: tuple[tuple[str, str], ...] = (),
) -> Request:
    fields = [*(("CSeq", c) for c in cseq), *extra]
    if session is not None:
        fields.append(("Session", session))
    return Request(method, target, Headers.of(fields), version=version)


@pytest.mark.parametrize(
    ("given", "receiver", "agreed", "due"),
    [
        # D-RCTP-25's order: each request also fails every check after the one that decides.
        (
            request("FETCH", "bad", (), None, "RCTP/1.0"),
            Role.SERVER,
            Agreed(),
            Refusal(501, "FETCH is not an RCTP/2.0 method", "R-RCTP-9"),
        ),
        (
            request("GO", "bad", (), None, "RCTP/1.0"),
            Role.SERVER,
            Agreed(),
            Refusal(505, "RCTP/1.0 is not RCTP/2.0", "R-RCTP-10"),
        ),
        (
            request("GO", "bad", (), None),
            Role.SERVER,
            Agreed(),
            Refusal(400, "the request has no single CSeq", "R-RCTP-11"),
        ),
        (
            request("GO", "bad", ("0",), None),
            Role.SERVER,
            Agreed(),
            Refusal(400, "CSeq '0' is not a number from 1 to 2147483647", "R-RCTP-11"),
        ),
        (
            request("GO", "bad", ("7",), "x", extra=(("Session", "y"),)),
            Role.SERVER,
            Agreed(),
            Refusal(400, "Session appears more than once", "R-RCTP-11"),
        ),
        (
            request("GO", "bad", ("7",), None),
            Role.CLIENT,
            Agreed(),
            Refusal(400, "CSeq 7, where 2 was next", "R-RCTP-4"),
        ),
        (
            request("GO", "bad", session=None),
            Role.CLIENT,
            Agreed(),
            Refusal(405, "a server does not send GO", "R-RCTP-25", "WRITE, STOP, BYE"),
        ),
        (
            request("GO", "bad", session=None),
            Role.SERVER,
            Agreed(),
            Refusal(400, "target: 'bad' is neither *, / nor a path starting with /", "R-RCTP-15"),
        ),
        (
            request("GO", session=None),
            Role.SERVER,
            Agreed(),
            Refusal(454, "the request does not name the session", "R-RCTP-19"),
        ),
        (
            request("GO", session="zzzzzzzzzzzz"),
            Role.SERVER,
            Agreed(),
            Refusal(454, "the request names another session", "R-RCTP-19"),
        ),
        (
            request("GO"),
            Role.SERVER,
            Agreed(),
            Refusal(455, "GO of a stream in state init", "R-RCTP-20"),
        ),
        # The session's states (D-RCTP-13).
        (
            request("GO", session=None),
            Role.SERVER,
            Agreed(SessionState.IDLE),
            Refusal(454, "no session yet: CONNECT first", "R-RCTP-17"),
        ),
        (request("CONNECT", session=None), Role.SERVER, Agreed(SessionState.IDLE), None),
        (
            request("CONNECT", session=None),
            Role.SERVER,
            Agreed(),
            Refusal(455, "this connection has a session already", "R-RCTP-20"),
        ),
        (request("CONNECT"), Role.SERVER, Agreed(), None),  # a refresh (R-RCTP-22)
        (
            request("READ"),
            Role.SERVER,
            Agreed(SessionState.CLOSING),
            Refusal(455, "the session is ending (BYE)", "R-RCTP-20"),
        ),
        (
            request("FETCH"),
            Role.SERVER,
            Agreed(SessionState.CLOSED),
            Refusal(
                None, "the session is over (D-RCTP-13: nothing is sent in closed)", "R-RCTP-23"
            ),
        ),
        # The streams' states (D-RCTP-14), and a client's for the server's WRITE (D-RCTP-27).
        (request("GO"), Role.SERVER, Agreed(streams={"/a": StreamState.READY}), None),
        (
            request("SETUP"),
            Role.SERVER,
            Agreed(streams={"/a": StreamState.PLAYING}),
            Refusal(455, "SETUP of a stream in state playing", "R-RCTP-20"),
        ),
        (
            request("STOP"),
            Role.CLIENT,
            Agreed(),
            Refusal(455, "STOP of a stream in state init", "R-RCTP-68"),
        ),
        (
            request("WRITE"),
            Role.CLIENT,
            Agreed(streams={"/a": StreamState.READY}),
            Refusal(455, "a data-change WRITE of an access in state ready", "R-RCTP-68"),
        ),
        (request("WRITE"), Role.CLIENT, Agreed(streams={"/a": StreamState.PLAYING}), None),
        (request("WRITE"), Role.SERVER, Agreed(), None),  # the node's business (D-RCTP-25)
        # A session the dissector could not read is told from no other: the next check decides.
        (
            request("GO", session="zzzzzzzzzzzz"),
            Role.SERVER,
            Agreed(session=None),
            Refusal(455, "GO of a stream in state init", "R-RCTP-20"),
        ),
    ],
)
def test_the_first_check_that_fails_decides(
    given: Request, receiver: Role, agreed: Agreed, due: Refusal | None
) -> None:
    assert first_refusal(given, receiver, 2, agreed) == due


def test_an_order_not_known_is_not_judged() -> None:
    """D-RCTP-6: a capture that starts mid-connection does not know which CSeq is next."""
    assert first_refusal(request(cseq=("7",)), Role.SERVER, None, Agreed()) is None


@pytest.mark.parametrize(
    ("cseq", "read"), [(("3",), 3), ((), None), (("3", "3"), None), (("x",), None)]
)
def test_the_cseq_of_a_request(cseq: tuple[str, ...], read: int | None) -> None:
    assert request_cseq(request(cseq=cseq)) == read
