"""The control connection: ordering, the core's own answers, timers, and random exchanges."""

from __future__ import annotations

from typing import Any

import pytest
from hypothesis import given
from hypothesis import strategies as st

from rcmlconf.rctp.connection import (
    Connection,
    ConnectionClosed,
    Event,
    KeepAliveDue,
    ProtocolFailure,
    RequestReceived,
    RequestRejected,
    ResponseReceived,
    SessionEnded,
    SessionTimedOut,
)
from rcmlconf.rctp.errors import LocalProtocolError
from rcmlconf.rctp.messages import METHODS
from rcmlconf.rctp.states import Role, SessionState, StreamState

SESSION = "abcdefgh1234;timeout=60"


def drain(conn: Connection) -> list[Event]:
    found = []
    while (event := conn.next_event()) is not None:
        found.append(event)
    return found


def pair(now: float = 0.0) -> tuple[Connection, Connection]:
    """A client and a server with a session open."""
    client, server = Connection(Role.CLIENT, now), Connection(Role.SERVER, now)
    client.send_request("CONNECT", "/", now=now)
    server.receive_data(client.data_to_send(), now)
    (connect,) = drain(server)
    assert isinstance(connect, RequestReceived)
    server.send_response(connect.request, 200, [("Session", SESSION)])
    client.receive_data(server.data_to_send(), now)
    drain(client), drain(server)
    return client, server


def received(server: Connection, client: Connection, now: float = 1.0) -> list[Event]:
    server.receive_data(client.data_to_send(), now)
    return drain(server)


def test_pipelined_requests_are_handed_over_one_answer_at_a_time() -> None:
    client, server = pair()
    for path in ("/a", "/b", "/c"):
        client.send_request("READ", path, now=1.0)
    handed = received(server, client)
    assert server.answers_due == 3
    answers = b""
    while handed:
        (event,) = handed  # one at a time: the next waits for this one's answer
        assert isinstance(event, RequestReceived)
        server.send_response(event.request, 200, body=event.request.target.encode())
        answers += server.data_to_send()
        handed = drain(server)
    assert server.answers_due == 0
    client.receive_data(answers, 1.0)
    bodies = [e.response.body for e in drain(client) if isinstance(e, ResponseReceived)]
    assert bodies == [b"/a", b"/b", b"/c"]


def test_a_pipelined_go_is_judged_after_its_setup_is_answered() -> None:
    """R-RCTP-13: SETUP and GO in one segment; GO is valid in the state SETUP's 200 leaves."""
    client, server = pair()
    client.send_request("SETUP", "/a", now=1.0)
    client.send_request("GO", "/a", now=1.0)
    (setup,) = received(server, client)
    assert isinstance(setup, RequestReceived)
    server.send_response(setup.request, 200)
    (go,) = drain(server)
    assert isinstance(go, RequestReceived)
    assert go.request.method == "GO"


def test_a_request_rejected_by_the_core_does_not_hold_up_the_next() -> None:
    client, server = pair()
    client.send_request("GO", "/never-set-up", now=1.0)
    client.send_request("READ", "/a", now=1.0)
    rejected, read = received(server, client)
    assert isinstance(rejected, RequestRejected)
    assert rejected.status == 455
    assert isinstance(read, RequestReceived)


def test_a_fatal_error_is_answered_after_the_requests_before_it() -> None:
    client, server = pair()
    client.send_request("READ", "/a", now=1.0)
    server.receive_data(client.data_to_send() + b"READ /b RCTP/2.0\nCSeq: 3\r\n\r\n", 1.0)
    waiting, failure = drain(server)
    assert isinstance(failure, ProtocolFailure)
    assert failure.error.status == 400
    assert server.data_to_send() == b""  # the READ before it is not answered yet
    assert server.answers_due == 1
    server.send_response(waiting.request, 200, body=b"\x00")
    out = server.data_to_send()
    assert out.index(b"200 OK") < out.index(b"400 Bad Request")
    assert server.answers_due == 0


@pytest.mark.parametrize(
    ("raw", "status", "rule"),
    [
        (b"GO /nowhere RCTP/2.0\r\nCSeq: 2\r\nSession: abcdefgh1234\r\n\r\n", 455, "R-RCTP-20"),
        (
            b"READ /a RCTP/2.0\r\nCSeq: 2\r\n"
            b"Session: abcdefgh1234\r\nSession: abcdefgh1234\r\n\r\n",
            400,
            "R-RCTP-11",
        ),
        (b"CONNECT / RCTP/2.0\r\nCSeq: 2\r\n\r\n", 455, "R-RCTP-20"),
        (b"READ /a RCTP/2.0\r\nCSeq: 2\r\n\r\n", 454, "R-RCTP-19"),
        (b"READ /a RCTP/2.0\r\nCSeq: 2\r\nSession: other-session\r\n\r\n", 454, "R-RCTP-19"),
        (b"READ /a/ RCTP/2.0\r\nCSeq: 2\r\nSession: abcdefgh1234\r\n\r\n", 400, "R-RCTP-15"),
        (b"READ /1a RCTP/2.0\r\nCSeq: 2\r\nSession: abcdefgh1234\r\n\r\n", 400, "R-RCTP-15"),
        (b"READ /a RCTP/2.0\r\nCSeq: 0\r\nSession: abcdefgh1234\r\n\r\n", 400, "R-RCTP-11"),
        # D-RCTP-25: the method is judged before the CSeq, the session before the stream state
        (b"FETCH /a RCTP/2.0\r\n\r\n", 501, "R-RCTP-9"),
        (b"GO /a RCTP/2.0\r\nCSeq: 2\r\n\r\n", 454, "R-RCTP-19"),
    ],
)
def test_the_server_core_answers_on_its_own(raw: bytes, status: int, rule: str) -> None:
    _, server = pair()
    server.receive_data(raw, 1.0)
    (event,) = drain(server)
    assert isinstance(event, RequestRejected)
    assert (event.status, event.rule) == (status, rule)
    assert server.data_to_send().startswith(f"RCTP/2.0 {status} ".encode())
    assert server.session_state is SessionState.OPEN  # and the connection goes on


def test_a_closing_session_takes_no_more_requests() -> None:
    _client, server = pair()
    server.send_request("BYE", "*", [("Reason", "shutdown")], now=1.0)
    server.receive_data(b"READ /a RCTP/2.0\r\nCSeq: 2\r\nSession: abcdefgh1234\r\n\r\n", 1.0)
    (event,) = drain(server)
    assert isinstance(event, RequestRejected)
    assert event.status == 455


def test_a_request_pipelined_after_bye_is_neither_answered_nor_applied() -> None:
    """D-RCTP-13: nothing is sent in closed. ACQUIRE behind BYE in one segment would otherwise
    be granted to a session that is over, and hold the privilege for ever."""
    client, server = pair()
    client.send_request("BYE", "*", now=1.0)
    client.send_request("ACQUIRE", "/a", now=1.0)
    events = received(server, client)
    for event in events:  # the application answers BYE if the core hands it over
        if isinstance(event, RequestReceived):
            assert event.request.method == "BYE"
            server.send_response(event.request, 200)
    events += drain(server)
    assert [type(e) for e in events if not isinstance(e, RequestReceived)] == [SessionEnded]
    assert server.session_state is SessionState.CLOSED
    answers = server.data_to_send()
    assert answers.count(b"RCTP/2.0 ") == 1  # BYE's 200, nothing for ACQUIRE
    assert answers.startswith(b"RCTP/2.0 200 OK\r\nCSeq: 2\r\n")
    assert server.answers_due == 0


def test_the_answer_to_connect_names_the_session_and_its_timeout() -> None:
    client, server = Connection(Role.CLIENT, 0), Connection(Role.SERVER, 0)
    client.send_request("CONNECT", "/", now=0)
    (connect,) = received(server, client)
    assert isinstance(connect, RequestReceived)
    with pytest.raises(LocalProtocolError):
        server.send_response(connect.request, 200)
    with pytest.raises(LocalProtocolError):
        server.send_response(connect.request, 200, [("Session", "abcdefgh1234")])


@pytest.mark.parametrize(
    "method", ["CONNECT", "ACQUIRE", "RELEASE", "READ", "SETUP", "GO", "PAUSE"]
)
def test_a_server_does_not_send_client_methods(method: str) -> None:
    _, server = pair()
    with pytest.raises(LocalProtocolError):
        server.send_request(method, "/a", now=1.0)


def test_server_session_timeout_sends_bye_and_activity_postpones_it() -> None:
    _, server = pair()
    assert server.get_timer() == 60.0
    server.note_activity(30.0)
    assert server.get_timer() == 90.0
    server.handle_timer(90.0)
    assert isinstance(drain(server)[0], SessionTimedOut)
    assert server.data_to_send().startswith(b"BYE * RCTP/2.0\r\n")
    assert server.session_state is SessionState.CLOSING
    assert server.get_timer() == 95.0  # R-RCTP-23: five seconds for the answer
    server.handle_timer(95.0)
    (ended,) = drain(server)
    assert isinstance(ended, SessionEnded)
    assert ended.reason == "no answer to BYE"
    assert server.session_state is SessionState.CLOSED


def test_the_client_is_reminded_to_keep_the_session_alive() -> None:
    client, _ = pair()
    client.send_request("READ", "/a", now=20.0)
    assert client.get_timer() == 50.0
    client.handle_timer(50.0)
    assert isinstance(drain(client)[0], KeepAliveDue)


def test_a_closed_connection_sends_nothing() -> None:
    _client, server = pair()
    server.receive_data(b"", 1.0)
    assert isinstance(drain(server)[0], ConnectionClosed)
    assert server.session_state is SessionState.CLOSED
    with pytest.raises(LocalProtocolError):
        server.send_request("WRITE", "/a", now=1.0)


def test_a_response_without_a_matching_request_ends_the_connection() -> None:
    client, _ = pair()
    client.send_request("READ", "/a", now=1.0)
    client.data_to_send()  # on its way
    client.receive_data(b"RCTP/2.0 200 OK\r\nCSeq: 9\r\n\r\n", 1.0)
    (failure,) = drain(client)
    assert isinstance(failure, ProtocolFailure)
    assert failure.error.rule == "R-RCTP-12"
    assert client.data_to_send() == b""  # a response is never answered


# -- random exchanges: no undefined state, no surprise exception -------------------------------

TARGETS = ["*", "/", "/drive", "/drive/wheels", "/head/control/tilt", "/x y", "drive"]
actions = st.lists(
    st.one_of(
        st.tuples(
            st.just("client"), st.sampled_from([*METHODS, "FETCH"]), st.sampled_from(TARGETS)
        ),
        st.tuples(
            st.just("server"),
            st.sampled_from(["WRITE", "STOP", "BYE", "READ"]),
            st.sampled_from(TARGETS),
        ),
        st.tuples(st.just("answer"), st.sampled_from([200, 404, 455, 471]), st.just("")),
        st.tuples(st.just("timer"), st.floats(0, 100), st.just("")),
        st.tuples(
            st.just("garbage"),
            st.sampled_from(["client", "server"]),
            st.sampled_from(["\n", "RCTP/2.0 200 OK\r\n\r\n", "X\r\n\r\n"]),
        ),
    ),
    max_size=30,
)


@given(actions)
def test_random_exchanges_stay_in_defined_states(steps: list[tuple[str, Any, Any]]) -> None:
    client, server = Connection(Role.CLIENT, 0.0), Connection(Role.SERVER, 0.0)
    cores = {"client": client, "server": server}
    pending: list[Any] = {"client": [], "server": []}
    now = 0.0
    for kind, first, second in steps:
        now += 0.5
        try:
            if kind in ("client", "server"):
                headers = (
                    [("Session", SESSION)] if (first == "CONNECT" and kind == "client") else []
                )
                cores[kind].send_request(
                    first, second if " " not in second else "/x", headers, now=now
                )
            elif kind == "answer":
                for name, queue in pending.items():
                    if queue:
                        request = queue.pop(0)
                        extra = [("Session", SESSION)] if request.method == "CONNECT" else []
                        cores[name].send_response(request, first, extra)
                        break
            elif kind == "timer":
                for core in cores.values():
                    core.handle_timer(now + first)
            else:
                cores[first].receive_data(second.encode(), now)
        except LocalProtocolError:
            pass
        for sender, receiver in (("client", "server"), ("server", "client")):
            cores[receiver].receive_data(cores[sender].data_to_send(), now)
        for name, core in cores.items():
            for event in drain(core):
                if isinstance(event, RequestReceived):
                    pending[name].append(event.request)
            assert core.session_state in SessionState
            assert all(state in StreamState for state in core.streams.values())


@pytest.mark.parametrize(
    "session",
    [None, "", "short", "abcdefgh1234;timeout=x"],
    ids=["none", "empty", "short-id", "bad-timeout"],
)
def test_a_connect_answered_200_without_a_readable_session_is_the_servers_fault(
    session: str | None,
) -> None:
    """R-RCTP-18: the client's core reports the server's answer as a protocol failure, with
    its offset and rule, and raises nothing else (it raised ValueTextError out of
    receive_data)."""
    client = Connection(Role.CLIENT, 0.0)
    client.send_request("CONNECT", "/", now=0.0)
    client.data_to_send()
    field = "" if session is None else f"Session: {session}\r\n"
    client.receive_data(f"RCTP/2.0 200 OK\r\nCSeq: 1\r\n{field}\r\n".encode(), 0.0)
    events = drain(client)
    failures = [e for e in events if isinstance(e, ProtocolFailure)]
    assert len(failures) == 1, events
    assert failures[0].error.rule == "R-RCTP-18"
    assert client.session is None
