"""RCTP control connections in captures: TCP reassembly (segments, pipelining, retransmissions,
out of order, holes), the states (D-RCTP-13, D-RCTP-14) and the order of checks (D-RCTP-25) as
the core's `Connection` applies them, request-to-response times, and the data stream's ports
learned from SETUP."""

from __future__ import annotations

import json
import random
from pathlib import Path
from typing import Any

import pytest
from hypothesis import example, given
from hypothesis import strategies as st
from support.pcaps import TCP_ACK, TCP_PSH, TCP_SYN, TcpFlow, dissect, ipv4_tcp, ipv4_udp, pcap

from rcmlconf.conformance.targets import REFERENCE_RCML
from rcmlconf.dissect import RCTP, RCTP_DATA, Options, Severity
from rcmlconf.dissect.control_results import Answer
from rcmlconf.rctp.connection import Connection, RequestReceived, RequestRejected
from rcmlconf.rctp.messages import METHODS, SERVER_METHODS
from rcmlconf.rctp.states import Role, SessionState
from rcmlconf.validate.validator import load_robot

TRANSCRIPTS = sorted(
    (Path(__file__).parents[2] / "vectors" / "rctp" / "transcripts").glob("*.json")
)
CLIENT, SERVER = ("10.0.0.2", 40000), ("10.0.0.7", 7330)
OTHER = {"client": "server", "server": "client"}
SESSION = "Session: abcdefgh1234\r\n"


def wire(text: str) -> bytes:
    return text.encode("latin-1")


def transcript_steps(
    path: Path,
) -> tuple[list[tuple[str, bytes]], list[tuple[int, str]], list[dict[str, Any]]]:
    """The bytes each side sent, in order; the requests the receiving core refused on its own,
    (status, rule); and its protocol failures."""
    steps = json.loads(path.read_text(encoding="utf-8"))["steps"]
    sent: list[tuple[str, bytes]] = []
    refused: list[tuple[int, str]] = []
    failures: list[dict[str, Any]] = []
    for step in steps:
        if "raw" in step:
            receiver = step["raw"]
            sender = OTHER[receiver]
        else:
            sender = step.get("from") or step["timer"]
            receiver = OTHER[sender]
        if step["wire"]:
            sent.append((sender, wire(step["wire"])))
        for event in step["events"]:
            if event["event"] == "RequestRejected":
                refused.append((event["status"], event["rule"]))
            elif event["event"] == "ProtocolFailure":
                failures.append({**event, "by": receiver})
        if step.get("reply"):
            sent.append((receiver, wire(step["reply"])))
    return sent, refused, failures


def capture_of(
    sent: list[tuple[str, bytes]], split: int | None = None, seed: int = 0, shuffle: bool = False
) -> bytes:
    """The exchange as a capture: each side's bytes in segments of `split` bytes (whole when
    None); `shuffle` sends each piece's segments out of order and some twice."""
    flow = TcpFlow(CLIENT, SERVER).handshake()
    rng = random.Random(seed)
    for who, data in sent:
        side = CLIENT if who == "client" else SERVER
        size = split or len(data)
        pieces = [(flow.next[side] + i, data[i : i + size]) for i in range(0, len(data), size)]
        flow.next[side] += len(data)
        if shuffle:
            rng.shuffle(pieces)
            pieces += rng.sample(pieces, min(2, len(pieces)))  # retransmissions
        for seq, piece in pieces:
            flow.send(side, piece, seq=seq)
    return pcap(flow.frames)


def summary(dissected: Any) -> list[tuple[str, str, int | None]]:
    return [(r.source, r.kind, r.sequence) for r in dissected.records if r.protocol == RCTP]


@pytest.mark.parametrize("path", TRANSCRIPTS, ids=lambda p: p.stem)
def test_transcript_refusals_are_the_cores(path: Path) -> None:
    """Every request the core's Connection refuses on its own in the transcript is one the
    dissector says must be refused, with the same status and rule, and no other."""
    sent, refused, failures = transcript_steps(path)
    dissected = dissect(capture_of(sent))
    (control,) = dissected.analysis.control
    found = [(status, rule) for _, status, rule in control.refused if status is not None]
    assert found == refused
    # Framing failures (the reader's: with a status) are malformed records at their offset; a
    # response that answers no request waiting (the connection's) is an error finding.
    malformed = [r.malformed for r in dissected.records if r.malformed is not None]
    framing = [f for f in failures if "status" in f]
    assert [m.rule for m in malformed] == [f["rule"] for f in framing]
    for m, f in zip(malformed, framing, strict=True):
        assert m.offset == f.get("offset", m.offset)
    unmatched = [f for f in failures if "status" not in f]
    errors = [x.rule for x in dissected.analysis.findings if x.severity is Severity.ERROR]
    assert len([r for r in errors if r in ("R-RCTP-3", "R-RCTP-12")]) >= len(unmatched)


@pytest.mark.parametrize("path", TRANSCRIPTS, ids=lambda p: p.stem)
def test_any_segmentation_gives_the_same_messages(path: Path) -> None:
    """R-RCTP-13: one byte a segment, or segments out of order and repeated, give the messages
    and findings of whole ones."""
    sent, _, _ = transcript_steps(path)
    whole = dissect(capture_of(sent))
    for split, shuffle in ((1, False), (7, True), (3, True)):
        pieces = dissect(capture_of(sent, split, seed=split, shuffle=shuffle))
        assert summary(pieces) == summary(whole)
        assert [(f.rule, f.severity) for f in pieces.analysis.findings] == [
            (f.rule, f.severity) for f in whole.analysis.findings
        ]
        (control,) = pieces.analysis.control
        if shuffle:
            assert control.retransmissions > 0
            assert control.out_of_order > 0


def session(*exchange: tuple[str, str]) -> Any:
    flow = TcpFlow(CLIENT, SERVER).handshake()
    for who, text in exchange:
        flow.send(CLIENT if who == "c" else SERVER, wire(text))
    return dissect(pcap(flow.frames))


CONNECT = ("c", "CONNECT /rover RCTP/2.0\r\nCSeq: 1\r\n\r\n")
CONNECTED = ("s", f"RCTP/2.0 200 OK\r\nCSeq: 1\r\n{SESSION[:-2]};timeout=60\r\n\r\n")


def test_pipelined_requests_and_their_answers() -> None:
    dissected = session(
        (
            "c",
            "CONNECT /rover RCTP/2.0\r\nCSeq: 1\r\n\r\n"
            f"SETUP /drive/wheels RCTP/2.0\r\nCSeq: 2\r\n{SESSION}"
            "Transport: udp;client_port=46000\r\n\r\n"
            f"GO /drive/wheels RCTP/2.0\r\nCSeq: 3\r\n{SESSION}\r\n",
        ),
        (
            "s",
            f"RCTP/2.0 200 OK\r\nCSeq: 1\r\n{SESSION[:-2]};timeout=60\r\n\r\n"
            f"RCTP/2.0 200 OK\r\nCSeq: 2\r\n{SESSION}Transport: udp;client_port=46000;"
            "server_port=7330;tag=0badcafe;mode=read;stream=1\r\n\r\n"
            f"RCTP/2.0 200 OK\r\nCSeq: 3\r\n{SESSION}Content-Length: 3\r\n\r\nabc",
        ),
    )
    kinds = [(r.kind, r.sequence) for r in dissected.records]
    assert kinds == [
        ("CONNECT", 1),
        ("SETUP", 2),
        ("GO", 3),
        ("200 OK", 1),
        ("200 OK", 2),
        ("200 OK", 3),
    ]
    answers = [r.extra for r in dissected.records if isinstance(r.extra, Answer)]
    assert [a.request.method for a in answers] == ["CONNECT", "SETUP", "GO"]
    assert all(a.elapsed > 0 for a in answers)
    assert dissected.records[-1].value.body == b"abc"
    # GO pipelined after SETUP is judged in the state SETUP's answer left: allowed.
    assert not dissected.analysis.findings
    (control,) = dissected.analysis.control
    assert control.streams == {"/drive/wheels": "playing"}
    assert control.session == "abcdefgh1234"
    assert control.timeout == 60
    assert set(control.response_times) == {"CONNECT", "SETUP", "GO"}


def test_a_method_in_a_state_that_does_not_allow_it() -> None:
    dissected = session(
        CONNECT,
        CONNECTED,
        ("c", f"GO /drive/wheels RCTP/2.0\r\nCSeq: 2\r\n{SESSION}\r\n"),
        ("s", f"RCTP/2.0 455 Method Not Valid in This State\r\nCSeq: 2\r\n{SESSION}\r\n"),
        ("c", f"PAUSE /drive/wheels RCTP/2.0\r\nCSeq: 3\r\n{SESSION}\r\n"),
        ("s", f"RCTP/2.0 200 OK\r\nCSeq: 3\r\n{SESSION}\r\n"),
    )
    findings = [(f.severity, f.rule, f.message) for f in dissected.analysis.findings]
    # The client's GO and PAUSE of a stream in init: warnings; the server's 200 to PAUSE: error.
    assert (Severity.WARNING, "R-RCTP-20", 3) in findings
    assert (Severity.WARNING, "R-RCTP-20", 5) in findings
    assert (Severity.ERROR, "R-RCTP-20", 6) in findings
    assert dissected.analysis.errors == 1


def test_requests_before_the_session_and_after_bye() -> None:
    dissected = session(
        ("c", "READ /x RCTP/2.0\r\nCSeq: 1\r\n\r\n"),
        ("s", "RCTP/2.0 454 Session Not Found\r\nCSeq: 1\r\n\r\n"),
        ("c", "CONNECT /rover RCTP/2.0\r\nCSeq: 2\r\n\r\n"),
        ("s", f"RCTP/2.0 200 OK\r\nCSeq: 2\r\n{SESSION[:-2]};timeout=60\r\n\r\n"),
        (
            "c",
            f"BYE * RCTP/2.0\r\nCSeq: 3\r\n{SESSION}\r\n"
            f"ACQUIRE / RCTP/2.0\r\nCSeq: 4\r\n{SESSION}\r\n",
        ),
        ("s", f"RCTP/2.0 200 OK\r\nCSeq: 3\r\n{SESSION}\r\n"),
    )
    (control,) = dissected.analysis.control
    assert [(status, rule) for _, status, rule in control.refused] == [
        (454, "R-RCTP-17"),
        (None, "R-RCTP-23"),  # pipelined after BYE: dropped unanswered (D-RCTP-13)
    ]
    assert control.state == "closed"
    assert not [f for f in dissected.analysis.findings if f.rule == "R-RCTP-5"]


def test_cseq_and_answer_faults() -> None:
    dissected = session(
        CONNECT,
        CONNECTED,
        ("c", f"READ /a RCTP/2.0\r\nCSeq: 5\r\n{SESSION}\r\n"),
        ("s", f"RCTP/2.0 200 OK\r\nCSeq: 4\r\n{SESSION}\r\n"),
        ("s", f"RCTP/2.0 200 OK\r\nCSeq: 9\r\n{SESSION}\r\n"),
        ("s", "STOP /a RCTP/2.0\r\n\r\n"),
    )
    rules = [(f.severity, f.rule) for f in dissected.analysis.findings]
    assert (Severity.ERROR, "R-RCTP-4") in rules  # CSeq 5 where 2 was next
    assert (Severity.ERROR, "R-RCTP-3") in rules  # an answer with another request's CSeq
    assert (Severity.ERROR, "R-RCTP-12") in rules  # an answer to no request
    assert rules.count((Severity.ERROR, "R-RCTP-3")) == 2  # the STOP has no CSeq


def test_unframeable_message_is_located_and_answered() -> None:
    flow = TcpFlow(CLIENT, SERVER).handshake()
    flow.send(CLIENT, b"CONNECT /rover RCTP/2.0\r\nCSeq: 1\r\n\r\n")
    flow.send(SERVER, CONNECTED[1].encode())
    flow.send(CLIENT, b"READ /a RCTP/2.0\r\nCSeq: 2\nSession: abcdefgh1234\r\n\r\n")
    flow.send(SERVER, b"RCTP/2.0 400 Bad Request\r\n\r\n")
    data = pcap(flow.frames)
    dissected = dissect(data)
    (bad,) = [r for r in dissected.records if r.malformed is not None]
    malformed = bad.malformed
    assert malformed is not None
    assert malformed.rule == "R-RCTP-1"
    stream_offset = len(b"CONNECT /rover RCTP/2.0\r\nCSeq: 1\r\n\r\nREAD /a RCTP/2.0\r\nCSeq: 2")
    assert malformed.offset == stream_offset
    assert malformed.file_offset is not None
    assert data[malformed.file_offset : malformed.file_offset + 1] == b"\n"
    # The 400 answers the broken request (D-RCTP-10): no "answers no request".
    assert not [f for f in dissected.analysis.findings if f.rule == "R-RCTP-12"]


def test_a_hole_the_capture_never_fills() -> None:
    flow = TcpFlow(CLIENT, SERVER).handshake()
    flow.send(CLIENT, b"CONNECT /rover RCTP/2.0\r\nCSeq: 1\r\n\r\n")
    flow.next[CLIENT] += 10  # ten bytes the capture lost
    flow.send(CLIENT, b"READ /a RCTP/2.0\r\nCSeq: 2\r\n\r\n")
    dissected = dissect(pcap(flow.frames))
    assert [r.kind for r in dissected.records] == ["CONNECT"]
    (note,) = dissected.findings("R-RCTP-13")
    assert "lost 10 bytes" in note
    (control,) = dissected.analysis.control
    assert control.holes == 1
    assert control.out_of_order == 1


def test_data_on_a_syn_is_the_first_bytes_of_the_stream() -> None:
    """TCP Fast Open (RFC 7413): the first request rides on the SYN, and a SYN sent again with it
    is a retransmission."""
    connect = b"CONNECT /rover RCTP/2.0\r\nCSeq: 1\r\n\r\n"
    read = b"READ /a RCTP/2.0\r\nCSeq: 2\r\n\r\n"
    syn = ipv4_tcp(CLIENT, SERVER, 999, TCP_SYN, connect)
    frames = [
        (1.0, syn),
        (1.1, syn),
        (1.2, ipv4_tcp(CLIENT, SERVER, 1000 + len(connect), TCP_ACK | TCP_PSH, read)),
    ]
    dissected = dissect(pcap(frames))
    assert [r.kind for r in dissected.records] == ["CONNECT", "READ"]
    assert not dissected.findings("R-RCTP-13")
    (control,) = dissected.analysis.control
    assert (control.holes, control.retransmissions) == (0, 1)


def test_mid_stream_capture_without_handshake() -> None:
    flow = TcpFlow(("10.0.0.2", 40001), ("10.0.0.7", 9000))
    flow.send(flow.server, b"RCTP/2.0 200 OK\r\nCSeq: 7\r\n\r\n")  # answers a request not seen
    flow.send(flow.client, f"READ /a RCTP/2.0\r\nCSeq: 8\r\n{SESSION}\r\n".encode())
    heuristic = dissect(pcap(flow.frames))
    assert [r.kind for r in heuristic.records] == ["200 OK", "READ"]
    assert not dissect(pcap(flow.frames), Options(heuristics=False)).records
    chosen = dissect(pcap(flow.frames), Options(heuristics=False, decode_as=(("rctp", 9000),)))
    assert len(chosen.records) == 2
    (control,) = chosen.analysis.control
    assert control.server == "10.0.0.7:9000"


def test_the_data_stream_is_found_by_its_setup() -> None:
    flow = TcpFlow(CLIENT, ("10.0.0.7", 9000)).handshake()
    flow.send(CLIENT, b"CONNECT /rover RCTP/2.0\r\nCSeq: 1\r\n\r\n")
    flow.send(flow.server, CONNECTED[1].encode())
    flow.send(
        CLIENT,
        f"SETUP /drive/wheels RCTP/2.0\r\nCSeq: 2\r\n{SESSION}"
        "Transport: udp;client_port=41000;mode=read\r\n\r\n".encode(),
    )
    flow.send(
        flow.server,
        f"RCTP/2.0 200 OK\r\nCSeq: 2\r\n{SESSION}Transport: udp;"
        "client_port=41000;server_port=42000;tag=0badcafe;mode=read;"
        "stream=1\r\n\r\n".encode(),
    )
    datagram = bytes.fromhex("020100010badcafeebe6bf40800000000101000400000001")
    frames = [
        *flow.frames,
        (flow.time + 1, ipv4_udp(("10.0.0.7", 42000), ("10.0.0.2", 41000), datagram)),
    ]
    options = Options(decode_as=(("rctp", 9000),), heuristics=False)
    dissected = dissect(pcap(frames), options)
    (packet,) = [r for r in dissected.records if r.protocol == RCTP_DATA]
    assert packet.kind == "DATA"
    (stream,) = dissected.analysis.streams
    assert stream.label == "stream 1 /drive/wheels (read)"
    # Sent from a port other than its server_port: R-RCTP-56.
    frames[-1] = (flow.time + 1, ipv4_udp(("10.0.0.7", 42001), ("10.0.0.2", 41000), datagram))
    assert "R-RCTP-56" in dissect(pcap(frames), options).rules()


def test_heuristics_ignore_other_tcp() -> None:
    flow = TcpFlow(("10.0.0.2", 40000), ("10.0.0.7", 80)).handshake()
    flow.send(flow.client, b"GET / HTTP/1.1\r\nHost: x\r\n\r\n")
    dissected = dissect(pcap(flow.frames))
    assert not dissected.records
    assert dissected.analysis.capture.other > 0


def test_fin_closes_the_session() -> None:
    frames = TcpFlow(CLIENT, SERVER).handshake()
    frames.send(CLIENT, CONNECT[1].encode()).send(SERVER, CONNECTED[1].encode())
    frames.frames.append(
        (frames.time + 1, ipv4_tcp(CLIENT, SERVER, frames.next[CLIENT], 0x11, b""))
    )
    (control,) = dissect(pcap(frames.frames)).analysis.control
    assert control.state == "closed"


def test_bodies_are_decoded_with_the_rcml() -> None:
    from rcmlconf.dissect.control_results import BodyValues
    from rcmlconf.rcml.model import AccessNode, DataNode
    from rcmlconf.rctp.bodies import ValuesCodec
    from rcmlconf.validate.validator import load_robot

    rover = load_robot(
        Path(__file__).parents[2] / "rcmlconf" / "reference" / "robots" / "rover" / "rover.rcml"
    )
    name = rover.node("/identity/info/name")
    settings = rover.node("/drive/settings")
    assert isinstance(name, DataNode)
    assert isinstance(settings, AccessNode)
    read = ValuesCodec((name,), "name", "R-RCTP-28").encode({"name": "rover"})
    written = ValuesCodec(settings.writable(), "settings", "R-RCTP-28")
    body = written.encode({node.name: node.minimum or 0 for node in settings.writable()})
    nodes = ", ".join(node.name for node in sorted(settings.writable(), key=lambda n: n.name))
    flow = TcpFlow(CLIENT, SERVER).handshake()
    for who, text in (
        CONNECT,
        CONNECTED,
        ("c", f"READ /identity/info/name RCTP/2.0\r\nCSeq: 2\r\n{SESSION}\r\n"),
        ("s", f"RCTP/2.0 200 OK\r\nCSeq: 2\r\n{SESSION}Content-Length: {len(read)}\r\n\r\n"),
    ):
        flow.send(CLIENT if who == "c" else SERVER, wire(text))
    flow.send(SERVER, read)
    flow.send(
        CLIENT,
        wire(
            f"WRITE /drive/settings RCTP/2.0\r\nCSeq: 3\r\n{SESSION}Nodes: "
            f"{nodes}\r\nContent-Length: {len(body)}\r\n\r\n"
        )
        + body,
    )
    with_rcml = dissect(pcap(flow.frames), Options(rcml=rover)).records
    answer = with_rcml[3].extra
    assert isinstance(answer, Answer)
    assert answer.values == {"name": "rover"}
    assert isinstance(with_rcml[4].extra, BodyValues)
    assert set(with_rcml[4].extra.values) == {node.name for node in settings.writable()}
    without = dissect(pcap(flow.frames)).records
    assert isinstance(without[3].extra, Answer)
    assert without[3].extra.values is None
    assert without[4].extra is None


# -- the core's own refusals, found due by the dissector -----------------------------------------

OURS, OTHERS = "abcdefgh1234", "zzzzzzzzzzzz"
Parts = tuple[str, str, str, str, str]
#: A request's parts: method, target, version, how its CSeq comes, the session it names. Each
#: part is most often right, so that an exchange goes through the states (D-RCTP-13, -14).
raw_requests = st.tuples(
    st.sampled_from([*METHODS, *sorted(SERVER_METHODS), "FETCH"]),
    st.sampled_from(["*", "*", "/", "/drive/wheels", "/drive/wheels", "drive", "/a/"]),
    st.sampled_from(["RCTP/2.0"] * 5 + ["RCTP/1.0"]),
    st.sampled_from(["next"] * 8 + ["skip", "none", "zero", "twice"]),
    st.sampled_from(["ours"] * 5 + ["none", "other", "twice"]),
)
RIGHT = ("RCTP/2.0", "next", "ours")
#: A raw request from the core's peer, or the core's own BYE (which puts it in closing).
steps = st.lists(st.one_of(raw_requests, st.just("BYE")), max_size=16)


def raw_request(parts: Parts, cseq: int) -> tuple[bytes, int]:
    """The request's bytes, and the CSeq its sender numbers its next request with."""
    method, target, version, numbering, session = parts
    lines = [f"{method} {target} {version}"]
    numbers = {"next": [str(cseq)], "skip": [str(cseq + 1)], "none": [], "zero": ["0"]}
    lines += [f"CSeq: {text}" for text in numbers.get(numbering, [str(cseq)] * 2)]
    sessions = {"ours": [OURS], "none": [], "other": [OTHERS]}
    lines += [f"Session: {given}" for given in sessions.get(session, [OURS] * 2)]
    after = {"next": cseq + 1, "skip": cseq + 2}.get(numbering, cseq)  # D-RCTP-6
    return wire("\r\n".join(lines) + "\r\n\r\n"), after


def core_exchange(
    receiver: Role, actions: list[Parts | str], opened: bool
) -> tuple[bytes, list[RequestRejected]]:
    """Raw requests sent to the `receiver`'s core, and its own BYEs (once the two cores opened a
    session, when `opened`), each request that passes answered 200 by the core's application: the
    capture of both directions, and the requests the core refused on its own."""
    client, server = Connection(Role.CLIENT, 0.0), Connection(Role.SERVER, 0.0)
    core, peer = (server, client) if receiver is Role.SERVER else (client, server)
    flow = TcpFlow(CLIENT, SERVER).handshake()
    refused: list[RequestRejected] = []

    def record(end: Connection, data: bytes) -> None:
        if data:
            flow.send(CLIENT if end is client else SERVER, data)

    def send(sender: Connection, data: bytes) -> bytes:
        """`data` from `sender` to the other end, which takes it: what that end answers."""
        record(sender, data)
        other = server if sender is client else client
        other.receive_data(data, 1.0)
        while (event := other.next_event()) is not None:
            if isinstance(event, RequestRejected):
                refused.append(event)
            elif isinstance(event, RequestReceived):
                opens = event.request.method == "CONNECT"
                other.send_response(event.request, 200, [("Session", f"{OURS};timeout=60")] * opens)
        return other.data_to_send()

    cseq = 1
    if opened:
        client.send_request("CONNECT", "/rover", now=0.0)
        send(server, send(client, client.data_to_send()))
        cseq += peer is client
    for action in actions:
        if isinstance(action, str):
            # Only while open: the peer never answers, and the dissector judges a request once
            # its sender's earlier ones are answered, as their receiver does (D-RCTP-25).
            if core.session_state is SessionState.OPEN:
                core.send_request(action, "*", now=1.0)
                record(core, core.data_to_send())
        else:
            data, cseq = raw_request(action, cseq)
            record(core, send(peer, data))  # nor does the peer read its answers
    return pcap(flow.frames), refused


@given(st.sampled_from(Role), steps, st.booleans())
# A BYE refused in closing ends nothing: the WRITE after it is still answered 455 (D-RCTP-13).
@example(Role.CLIENT, ["BYE", ("BYE", "*", *RIGHT), ("WRITE", "/drive/wheels", *RIGHT)], True)
def test_what_the_core_refuses_the_dissector_finds_due(
    receiver: Role, actions: list[Parts | str], opened: bool
) -> None:
    """D-RCTP-25: the requests a core refuses on its own, in any state an exchange leads to, are
    the ones the dissector finds due a refusal, with the same status, rule and reason, and the
    core's answers are the ones due."""
    data, refused = core_exchange(receiver, actions, opened)
    dissected = dissect(data)
    (control,) = dissected.analysis.control
    address, port = CLIENT if receiver is Role.SERVER else SERVER
    peer = f"{address}:{port}"
    sent = {r.number for r in dissected.records if r.source == peer}
    due = [(n, status, rule) for n, status, rule in control.refused if n in sent and status]
    assert [(status, rule) for _, status, rule in due] == [(e.status, e.rule) for e in refused]
    for (number, _, rule), event in zip(due, refused, strict=True):
        (text,) = [
            f.text
            for f in dissected.analysis.findings
            if (f.message, f.rule) == (number, rule) and f.severity is not Severity.ERROR
        ]
        assert f": {event.reason}; " in text
    answered = [f.text for f in dissected.analysis.findings if " answered " in f.text]
    assert not [text for text in answered if text.startswith(("the client", "the server"))]


def test_an_answer_may_echo_the_cseq_of_a_request_that_cannot_be_framed() -> None:
    """D-RCTP-10: the receiver may have read a CSeq the capture cannot tell (found by fuzz)."""
    dissected = session(
        ("c", "\r\nCSeq: 1\r\n\r\n"),
        ("s", "RCTP/2.0 400 Bad Request\r\nCSeq: 1\r\n\r\n"),
    )
    assert not dissected.findings("R-RCTP-3")


def _setup_answered_200(path: str, asked: str = "udp;mode=sideways", given: str = "") -> Any:
    """SETUP of `path` with the Transport `asked` (by default one a server cannot read),
    answered 200 with the Transport `given` (by default none), judged with the reference
    robot's RCML."""
    flow = TcpFlow(CLIENT, SERVER).handshake()
    setup = f"SETUP {path} RCTP/2.0\r\nCSeq: 2\r\n{SESSION}Transport: {asked}\r\n\r\n"
    answered = f"Transport: {given}\r\n" if given else ""
    answer = f"RCTP/2.0 200 OK\r\nCSeq: 2\r\n{SESSION}{answered}\r\n"
    for who, text in (CONNECT, CONNECTED, ("c", setup), ("s", answer)):
        flow.send(CLIENT if who == "c" else SERVER, wire(text))
    return dissect(pcap(flow.frames), Options(rcml=load_robot(REFERENCE_RCML)))


def test_an_event_access_setup_names_no_data_stream() -> None:
    """The RCML says /drive/settings is an event access: a Transport its SETUP carries is not
    the server's to answer (D-RCTP-26), and a 200 without one breaks nothing (found by fuzz)."""
    assert not _setup_answered_200("/drive/settings").findings("R-RCTP-38")
    # The same on SETUP of a stream access: 461 was due (R-RCTP-38).
    found = _setup_answered_200("/drive/wheels").findings("R-RCTP-38")
    assert any("461 is due" in text for text in found)


def test_a_server_may_ignore_its_own_transport_parameters_in_a_setup() -> None:
    """D-RCTP-18: server_port, tag and stream are the server's to give. A bad one in a SETUP
    may be ignored (found by fuzz: `stream=0`); a bad client_port may not."""
    given = "udp;client_port=5000;server_port=7331;tag=0badcafe;mode=both;stream=1"
    for asked in ("stream=0", "tag=zz", "server_port=0;stream=999"):
        ignored = _setup_answered_200("/drive/wheels", f"udp;client_port=5000;{asked}", given)
        assert not ignored.findings("R-RCTP-38"), asked
    bad_port = _setup_answered_200("/drive/wheels", "udp;client_port=0;mode=both", given)
    assert any("461 is due" in text for text in bad_port.findings("R-RCTP-38"))


def test_a_server_may_serve_a_cseq_out_of_order() -> None:
    """D-RCTP-6: R-RCTP-4 binds the sender; its receiver need not check (found by fuzz)."""
    dissected = session(
        CONNECT,
        CONNECTED,
        ("c", f"READ /a RCTP/2.0\r\nCSeq: 5\r\n{SESSION}\r\n"),
        ("s", f"RCTP/2.0 200 OK\r\nCSeq: 5\r\n{SESSION}\r\n"),
    )
    errors = [
        (f.rule, f.message) for f in dissected.analysis.findings if f.severity is Severity.ERROR
    ]
    assert errors == [("R-RCTP-4", 3)]  # the client's request, not the server's answer
