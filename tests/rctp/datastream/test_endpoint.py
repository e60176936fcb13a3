"""One session's data stream at both ends (specs/rctp-2.0.md §6), wired by hand, time by hand."""

from __future__ import annotations

from functools import partial

import pytest
from hypothesis import given
from hypothesis import strategies as st
from support.robots import access

from rcmlconf.rctp.datastream.endpoint import HEARTBEAT_EVERY, RETRY_EVERY, SENDS, Endpoint
from rcmlconf.rctp.datastream.events import (
    ClockUpdated,
    FlowAnswered,
    FlowRequested,
    FlowUnanswered,
    PacketDropped,
    PayloadIgnored,
    StreamEvent,
    StreamTimedOut,
    ValuesReceived,
)
from rcmlconf.rctp.datastream.flow import (
    Direction,
    HeartbeatRequest,
    IntervalGet,
    IntervalGetAck,
    IntervalSet,
    IntervalSetAck,
    Nack,
    NackReason,
    TimeoutSet,
    TimeoutSetAck,
    UnknownRequest,
)
from rcmlconf.rctp.datastream.packets import (
    DataPayload,
    FlowPayload,
    MalformedFlowPayload,
    Packet,
    pull_packet,
    push_packet,
)
from rcmlconf.rctp.errors import LocalProtocolError
from rcmlconf.rctp.states import Role
from rcmlconf.values import Value

TAG = 0xA3F19C07
SERVER_ADDR = ("127.0.0.1", 7331)
CLIENT_ADDR = ("127.0.0.1", 40000)
WHEELS = "/drive/wheels"
#: The robot's clock runs 2.5 s ahead of the client's.
ROBOT_AHEAD = 2.5
UNIX = 1_800_000_000.0


def ends(mode: str = "both", first: int = 100) -> tuple[Endpoint, Endpoint]:
    server = Endpoint(
        Role.SERVER, TAG, peer=CLIENT_ADDR, first_sequence=first, unix_offset=UNIX + ROBOT_AHEAD
    )
    client = Endpoint(
        Role.CLIENT, TAG, peer=SERVER_ADDR, first_sequence=7, unix_offset=UNIX, precision=1e-3
    )
    for end in (server, client):
        end.add_stream(1, access(WHEELS), mode)
    return server, client


def events(end: Endpoint) -> list[StreamEvent]:
    found = []
    while (event := end.next_event()) is not None:
        found.append(event)
    return found


def deliver(sender: Endpoint, receiver: Endpoint, now: float) -> list[StreamEvent]:
    source = SERVER_ADDR if sender.role is Role.SERVER else CLIENT_ADDR
    for datagram in sender.datagrams_to_send(now):
        assert receiver.receive_datagram(datagram, source, now)
    return events(receiver)


def server_body(server: Endpoint, **values: Value) -> bytes:
    codec = server.streams[1].codecs[Direction.READ]
    defaults: dict[str, Value] = {"left": 0.0, "right": 0.0, "odometry": (0.0, 0.0, 0.0)}
    return codec.encode({**defaults, **values})


# -- DATA ------------------------------------------------------------------------------------------


def test_a_playing_stream_is_due_once_per_interval_and_its_values_arrive() -> None:
    server, client = ends()
    assert server.due(0.0) == ()  # not playing: nothing is due (R-RCTP-44)
    server.play(1, 0.0)
    client.play(1, 0.0)
    assert server.due(0.0) == (1,)
    server.send_data({1: server_body(server, left=0.5)}, 0.0)
    (received,) = [e for e in deliver(server, client, 0.001) if isinstance(e, ValuesReceived)]
    assert received.stream == 1
    assert received.values == {"left": 0.5, "right": 0.0, "odometry": (0.0, 0.0, 0.0)}
    assert server.due(0.010) == ()
    assert server.due(0.0195) == (1,)  # within the slack of 20 ms
    server.send_data({1: server_body(server)}, 0.020)
    assert server.due(0.030) == ()


def test_a_late_application_does_not_make_up_lost_beats() -> None:
    server, _ = ends()
    server.play(1, 0.0)
    server.send_data({1: server_body(server)}, 0.0)
    server.send_data({1: server_body(server)}, 0.5)  # 24 beats late
    assert server.due(0.51) == ()
    assert server.due(0.52) == (1,)


def test_only_newer_packets_are_applied() -> None:
    server, client = ends()
    server.play(1, 0.0)
    client.play(1, 0.0)
    server.send_data({1: server_body(server, left=0.25)}, 0.0)
    first = server.datagrams_to_send(0.0)
    server.send_data({1: server_body(server, left=0.5)}, 0.02)
    second = server.datagrams_to_send(0.02)
    for datagram in second + first + second:  # reordered, then repeated
        client.receive_datagram(datagram, SERVER_ADDR, 0.03)
    found = events(client)
    assert [e.values["left"] for e in found if isinstance(e, ValuesReceived)] == [0.5]
    ignored = [e for e in found if isinstance(e, PayloadIgnored)]
    assert [e.rule for e in ignored] == ["R-RCTP-43", "R-RCTP-43"]
    counts = client.sequences.counts
    assert (counts.newer, counts.late, counts.duplicates) == (1, 1, 1)


def test_sequence_numbers_follow_one_another_and_wrap() -> None:
    server, _ = ends(first=0xFFFF)
    server.play(1, 0.0)
    sequences = []
    for beat in range(3):
        server.send_data({1: server_body(server)}, beat * 0.02)
        sequences += [pull_packet(d).sequence for d in server.datagrams_to_send(beat * 0.02)]
    assert sequences == [0xFFFF, 0, 1]  # R-RCTP-41


def test_values_outside_a_range_are_not_applied() -> None:
    server, client = ends()
    server.play(1, 0.0)
    client.play(1, 0.0)
    client.send_data(
        {1: client.streams[1].codecs[Direction.WRITE].encode({"left": 0.5, "right": 1.75})}, 0.0
    )
    found = deliver(client, server, 0.001)
    assert not [e for e in found if isinstance(e, ValuesReceived)]
    (ignored,) = [e for e in found if isinstance(e, PayloadIgnored)]
    assert ignored.rule == "R-RCTP-58"
    assert "1.75" in ignored.reason


def test_a_body_that_does_not_decode_is_placed_in_the_datagram() -> None:
    _server, client = ends()
    client.play(1, 0.0)
    datagram = push_packet(Packet(1, TAG, 0, (DataPayload(1, b"\x00\x01"),)))
    assert client.receive_datagram(datagram, SERVER_ADDR, 0.0)
    (ignored,) = events(client)
    assert isinstance(ignored, PayloadIgnored)
    assert ignored.rule == "R-RCTP-40"
    assert ignored.offset is not None
    assert ignored.offset >= 20


@pytest.mark.parametrize(
    ("source", "datagram", "rule"),
    [
        (("10.0.0.9", 40000), None, "R-RCTP-42"),
        (CLIENT_ADDR, push_packet(Packet(1, TAG ^ 1, 0, (DataPayload(1, b""),))), "R-RCTP-42"),
        (CLIENT_ADDR, b"\x02\x01\x00", "R-RCTP-39"),
        (CLIENT_ADDR, b"\x01" + bytes(20), "R-RCTP-39"),
    ],
    ids=["stranger", "wrong tag", "short", "version 1"],
)
def test_packets_not_of_the_session_are_dropped_unanswered(
    source: tuple[str, int], datagram: bytes | None, rule: str
) -> None:
    server, client = ends()
    if datagram is None:
        client.heartbeat(0.0)
        (datagram,) = client.datagrams_to_send(0.0)
    assert not server.receive_datagram(datagram, source, 0.0)
    (dropped,) = events(server)
    assert isinstance(dropped, PacketDropped)
    assert dropped.rule == rule
    assert server.datagrams_to_send(0.0) == []


def test_streams_due_together_share_a_packet() -> None:
    server, client = ends()
    for end in (server, client):
        end.add_stream(2, access("/sensors/range"), "read")
        end.play(1, 0.0)
        end.play(2, 0.0)
    range_body = (
        server.streams[2].codecs[Direction.READ].encode({"ir": (1, 2, 3, 4, 5, 6), "battery": 50.0})
    )
    assert server.due(0.0) == (1, 2)
    server.send_data({1: server_body(server), 2: range_body}, 0.0)
    (datagram,) = server.datagrams_to_send(0.0)
    assert [p.stream for p in pull_packet(datagram).payloads] == [1, 2]


def test_payloads_beyond_one_datagram_go_in_the_next() -> None:
    server, _ = ends()
    for stream in range(1, 4):
        server.add_stream(stream, access(WHEELS), "read")
        server.play(stream, 0.0)
    server.send_data({stream: bytes(30000) for stream in range(1, 4)}, 0.0)
    datagrams = server.datagrams_to_send(0.0)
    assert [len(pull_packet(d).payloads) for d in datagrams] == [2, 1]


def test_only_a_playing_stream_of_this_ends_direction_sends() -> None:
    server, client = ends(mode="read")
    with pytest.raises(LocalProtocolError):
        server.send_data({1: b""}, 0.0)  # set up, not playing
    client.play(1, 0.0)
    with pytest.raises(LocalProtocolError):
        client.send_data({1: b""}, 0.0)  # a read stream: the client sends no DATA
    assert client.due(0.0) == ()


# -- receive timeout -------------------------------------------------------------------------------


def test_a_stream_without_data_for_its_timeout_is_lost_once() -> None:
    server, client = ends()
    server.play(1, 0.0)
    assert server.get_timer() == 0.0  # the first send
    server.send_data({1: server_body(server)}, 0.0)
    client.play(1, 0.0)
    client.send_data(
        {1: client.streams[1].codecs[Direction.WRITE].encode({"left": 0.0, "right": 0.0})}, 0.0
    )
    deliver(client, server, 0.5)  # the write timeout is 1 s: counted from 0.5 now
    server.handle_timer(1.4)
    assert not [e for e in events(server) if isinstance(e, StreamTimedOut)]
    server.handle_timer(1.5)
    assert events(server) == [StreamTimedOut(1, Direction.WRITE)]
    server.handle_timer(5.0)
    assert events(server) == []


# -- FLOW ------------------------------------------------------------------------------------------


def answer_of(server: Endpoint, client: Endpoint, now: float = 0.0) -> FlowAnswered:
    deliver(client, server, now)
    (answered,) = [e for e in deliver(server, client, now) if isinstance(e, FlowAnswered)]
    return answered


def test_the_owner_sets_an_interval_no_shorter_than_the_rcmls() -> None:
    server, client = ends()
    client.request(partial(IntervalSet, direction=Direction.READ, interval=10_000), 1, 0.0)
    refused = answer_of(server, client)
    assert refused.answer == Nack(0, 3, NackReason.VALUE_REFUSED)  # R-RCTP-47
    client.request(partial(IntervalSet, direction=Direction.READ, interval=100_000), 1, 0.0)
    assert answer_of(server, client).answer == IntervalSetAck(1, Direction.READ, 100_000)
    assert server.streams[1].intervals[Direction.READ] == 100_000
    assert client.streams[1].intervals[Direction.READ] == 100_000  # both ends agree
    server.play(1, 0.0)
    server.send_data({1: server_body(server)}, 0.0)
    assert server.due(0.05) == ()
    assert server.due(0.1) == (1,)


def test_a_timeout_shorter_than_twice_the_interval_is_refused() -> None:
    server, client = ends()
    client.request(partial(TimeoutSet, direction=Direction.WRITE, timeout=30_000), 1, 0.0)
    assert answer_of(server, client).answer.reason is NackReason.VALUE_REFUSED  # type: ignore[union-attr]
    client.request(partial(TimeoutSet, direction=Direction.WRITE, timeout=40_000), 1, 0.0)
    assert answer_of(server, client).answer == TimeoutSetAck(1, Direction.WRITE, 40_000)
    assert server.streams[1].timeouts[Direction.WRITE] == 40_000


@pytest.mark.parametrize(
    ("build", "stream", "reason"),
    [
        (
            partial(IntervalSet, direction=Direction.WRITE, interval=100_000),
            1,
            NackReason.NOT_PERMITTED,
        ),
        (
            partial(TimeoutSet, direction=Direction.READ, timeout=10_000_000),
            1,
            NackReason.NOT_PERMITTED,
        ),
        (partial(IntervalGet, direction=Direction.READ), 9, NackReason.UNKNOWN_STREAM),
        (partial(UnknownRequest, operation=77, fields=b"\x01"), 0, NackReason.UNKNOWN_OPERATION),
    ],
    ids=["not the owner of an interval", "not the owner of a timeout", "no such stream", "unknown"],
)
def test_requests_the_server_cannot_grant_are_refused(
    build: partial[object], stream: int, reason: NackReason
) -> None:
    server, client = ends()
    client.request(build, stream, 0.0)  # type: ignore[arg-type]
    answered = answer_of(server, client)
    assert isinstance(answered.answer, Nack)
    assert answered.answer.reason is reason


def test_a_direction_the_mode_does_not_carry_is_no_stream() -> None:
    server, client = ends(mode="read")
    client.request(partial(IntervalGet, direction=Direction.WRITE), 1, 0.0)
    assert answer_of(server, client).answer.reason is NackReason.UNKNOWN_STREAM  # type: ignore[union-attr]
    client.request(partial(IntervalGet, direction=Direction.READ), 1, 0.0)
    assert answer_of(server, client).answer == IntervalGetAck(1, Direction.READ, 20_000)


def test_a_malformed_request_is_answered_nack_5_and_the_rest_of_its_packet_is_read() -> None:
    server, client = ends()
    server.play(1, 0.0)
    client.play(1, 0.0)
    # A heartbeat request 6 bytes short of its T1.
    broken = MalformedFlowPayload(0, b"\x00\x01\x00\x05\x00\x00", "", 0)
    data = DataPayload(
        1, client.streams[1].codecs[Direction.WRITE].encode({"left": 1.0, "right": 1.0})
    )
    datagram = push_packet(Packet(1, TAG, 0, (broken, data)))
    assert server.receive_datagram(datagram, CLIENT_ADDR, 0.0)
    found = events(server)
    assert [type(e) for e in found] == [PayloadIgnored, ValuesReceived]
    assert found[0].rule == "R-RCTP-52"  # type: ignore[union-attr]
    (reply,) = server.datagrams_to_send(0.0)
    (nack,) = pull_packet(reply).payloads
    assert nack == FlowPayload(0, Nack(5, 1, NackReason.MALFORMED))  # R-RCTP-53


def test_a_request_is_sent_five_times_then_given_up() -> None:
    _, client = ends()
    request = client.heartbeat(0.0)
    sent = len(client.datagrams_to_send(0.0))
    now = 0.0
    for _ in range(SENDS + 2):
        now += RETRY_EVERY
        client.handle_timer(now)
        sent += len(client.datagrams_to_send(now))
    assert sent == SENDS
    assert [e for e in events(client) if isinstance(e, FlowUnanswered)] == [
        FlowUnanswered(0, request)
    ]


def test_a_repeated_request_gets_the_answer_already_given() -> None:
    server, client = ends()
    client.request(partial(IntervalSet, direction=Direction.READ, interval=100_000), 1, 0.0)
    (first,) = client.datagrams_to_send(0.0)
    server.receive_datagram(first, CLIENT_ADDR, 0.0)
    server.streams[1].intervals[Direction.READ] = 200_000  # changed since: the answer is kept
    client.handle_timer(RETRY_EVERY)
    (again,) = client.datagrams_to_send(RETRY_EVERY)
    server.receive_datagram(again, CLIENT_ADDR, RETRY_EVERY)
    answers = [p for d in server.datagrams_to_send(RETRY_EVERY) for p in pull_packet(d).payloads]
    assert answers == [FlowPayload(1, IntervalSetAck(0, Direction.READ, 100_000))] * 2
    requested = [e for e in events(server) if isinstance(e, FlowRequested)]
    assert len(requested) == 1  # the repeat is not a new request


def test_heartbeats_estimate_the_robots_clock() -> None:
    server, client = ends()
    client.play(1, 0.0)
    assert client.get_timer() == 0.0
    client.handle_timer(0.0)
    deliver(client, server, 0.004)  # 4 ms out, 6 ms back: the estimate is off by 1 ms at most
    (updated,) = [e for e in deliver(server, client, 0.010) if isinstance(e, ClockUpdated)]
    estimate = updated.estimate
    assert estimate.offset == pytest.approx(ROBOT_AHEAD - 0.001, abs=1e-6)
    assert estimate.delay == pytest.approx(0.010, abs=1e-6)
    assert estimate.uncertainty == pytest.approx(0.005 + 1e-3, abs=1e-6)
    client.handle_timer(HEARTBEAT_EVERY - 0.01)  # R-RCTP-49: then every 5 s
    assert client.datagrams_to_send(HEARTBEAT_EVERY - 0.01) == []
    client.handle_timer(HEARTBEAT_EVERY)
    (datagram,) = client.datagrams_to_send(HEARTBEAT_EVERY)
    (payload,) = pull_packet(datagram).payloads
    assert isinstance(payload, FlowPayload)
    assert isinstance(payload.flow, HeartbeatRequest)
    client.pause(1)
    # Nothing plays: no more heartbeats or sends, only the last heartbeat's retry.
    assert client.get_timer() == pytest.approx(HEARTBEAT_EVERY + RETRY_EVERY)


def test_a_client_beats_as_often_as_it_is_told() -> None:
    """D-RCTP-31's scenario beats every second, not every HEARTBEAT_EVERY."""
    client = Endpoint(Role.CLIENT, TAG, peer=SERVER_ADDR, heartbeat_every=1.0)
    client.add_stream(1, access(WHEELS), "read")
    client.play(1, 0.0)

    def heartbeats(now: float) -> set[int]:
        client.handle_timer(now)
        payloads = [p for d in client.datagrams_to_send(now) for p in pull_packet(d).payloads]
        return {
            p.flow.request_id
            for p in payloads
            if isinstance(p, FlowPayload) and isinstance(p.flow, HeartbeatRequest)
        }

    assert heartbeats(0.0) == {0}
    assert 1 not in heartbeats(0.99)  # the first one's repeat only
    assert 1 in heartbeats(1.0)


def test_a_server_sends_no_heartbeats() -> None:
    server, _ = ends()
    server.play(1, 0.0)
    server.send_data({1: server_body(server)}, 0.0)
    server.handle_timer(0.0)
    (datagram,) = server.datagrams_to_send(0.0)
    assert not [p for p in pull_packet(datagram).payloads if isinstance(p, FlowPayload)]


# -- anything at all -------------------------------------------------------------------------------


@given(st.lists(st.binary(max_size=80), max_size=20))
def test_garbage_never_escapes_as_an_exception(datagrams: list[bytes]) -> None:
    server, client = ends()
    for end in (server, client):
        end.play(1, 0.0)
    for datagram in datagrams:
        server.receive_datagram(b"\x02" + datagram, CLIENT_ADDR, 0.0)
        client.receive_datagram(datagram, SERVER_ADDR, 0.0)
    events(server), events(client)
    for datagram in server.datagrams_to_send(0.0):
        pull_packet(datagram)  # whatever it answered is well formed


@given(st.lists(st.integers(0, 0xFFFF), max_size=30))
def test_requests_in_packets_of_any_order_are_answered_once_each(sequences: list[int]) -> None:
    """FLOW is handled in stale packets too (D-RCTP-21); repeated ids are not new requests."""
    server, _ = ends()
    seen: set[int] = set()
    for sequence in sequences:
        request_id = sequence % 7
        payload = FlowPayload(0, HeartbeatRequest(request_id, 1))
        server.receive_datagram(push_packet(Packet(sequence, TAG, 0, (payload,))), CLIENT_ADDR, 0.0)
        seen.add(request_id)
    requested = [e for e in events(server) if isinstance(e, FlowRequested)]
    assert len(requested) == len(seen)


def test_a_stream_with_nothing_to_send_waits_for_its_next_beat() -> None:
    _, client = ends()
    client.play(1, 0.0)
    assert client.due(0.0) == (1,)
    client.skip([1], 0.0)
    assert client.due(0.0) == ()
    assert client.datagrams_to_send(0.0) == []  # nothing was sent
    assert client.due(0.02) == (1,)
