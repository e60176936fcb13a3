"""The bounded transcript (issue 27): whatever a target sends, a case keeps the first and the last
lines, and of each flow the first and the last payloads, counts the rest, and says once where it
left them out: among the entries and the lines, in --json's `left_out`, and in the capture (pcapng,
a comment on the flow's next packet; a TCP flow's numbers go on past the bytes left out, so that a
dissector sees a hole and finds nothing the target did not do). `Kept`, the list that does it for
the transcript and the probes, is checked against a plain list."""

from __future__ import annotations

import io

from hypothesis import given
from hypothesis import strategies as st
from support.pcaps import dissect

from rcmlconf.conformance.kept import Kept
from rcmlconf.conformance.reports.exchange import exchange_json, left_out_json
from rcmlconf.conformance.transcript import FLOWS, KEPT, KEPT_BYTES, LINES, Transcript
from rcmlconf.dissect import Options
from rcmlconf.pcap.reader import Capture
from rcmlconf.pcap.writer import Gap, Payload, write_pcap

HARNESS, SERVER, ROBOT = ("127.0.0.1", 40000), ("127.0.0.1", 7330), ("127.0.0.1", 7340)


@given(
    st.integers(0, 6),
    st.integers(0, 6),
    st.lists(st.integers(0, 9), max_size=40),
    st.one_of(st.none(), st.integers(0, 20)),
)
def test_kept_is_a_list_that_forgets_its_middle(
    head: int, tail: int, sizes: list[int], most: int | None
) -> None:
    kept: Kept[tuple[int, int]] = Kept(head, tail, lambda item: item[1], most)
    items = list(enumerate(sizes))  # (place, size): each item unique, its place in it
    for item in items:
        kept.append(item)
    assert len(kept) == len(items)
    assert list(kept) == sorted(kept, key=lambda item: item[0])  # in order
    assert list(reversed(kept)) == list(kept)[::-1]
    assert len(kept.head) <= head
    assert len(kept.tail) <= max(tail, 1 if kept.tail else 0)
    if items and tail:  # the last is always kept
        assert list(kept)[-1] == items[-1]
    left_out = [item for item in items if item not in list(kept)]
    assert kept.left_out == len(left_out)
    assert kept.left_out_size == sum(size for _, size in left_out)
    assert (kept.first_left_out, kept.last_left_out) == (
        (left_out[0], left_out[-1]) if left_out else (None, None)
    )
    for place, item in kept.places():  # each kept at its place among all
        assert items[place] == item == kept[place]
        assert kept.index(item) == place
        assert kept[place - len(items)] == item
    for start in range(len(items) + 1):
        assert kept[start:] == [i for i in items[start:] if i in list(kept)]
    if most is not None and kept.head:  # each end within its bytes, or one item alone
        assert sum(s for _, s in kept.head) <= most or len(kept.head) == 1


def test_a_flood_keeps_the_first_and_last_of_each_flow_and_counts_the_rest() -> None:
    transcript = Transcript()
    transcript.packet("udp", HARNESS, ROBOT, b"hello")
    flood = 5 * KEPT
    for number in range(flood):
        transcript.packet("udp", ROBOT, HARNESS, number.to_bytes(4, "big"))
        transcript.note(f"<- UPLINK #{number}")
    entries = transcript.entries
    payloads = [e.payload for e in entries if e.payload is not None]
    assert len(payloads) == 1 + 2 * KEPT  # the harness's flow whole, the robot's two ends
    numbers = [int.from_bytes(p.data, "big") for p in payloads if p.source == ROBOT]
    assert numbers == [*range(KEPT), *range(flood - KEPT, flood)]
    gaps = left_out_json(entries)
    assert {(g["what"], g["count"]) for g in gaps} == {
        ("udp", flood - 2 * KEPT),
        ("lines", flood - 2 * LINES),
    }
    udp = next(g for g in gaps if g["what"] == "udp")
    assert (udp["source"], udp["destination"], udp["bytes"]) == (
        "127.0.0.1:7340",
        "127.0.0.1:40000",
        4 * (flood - 2 * KEPT),
    )
    # The note is where the payloads were left out: after the first KEPT, before the last.
    found = exchange_json(entries)
    notes = [i for i, e in enumerate(found) if e["transport"] == "udp" and e["bytes"] is None]
    assert len(notes) == 1
    before = [e for e in found[: notes[0]] if e["bytes"] and e["source"] == "127.0.0.1:7340"]
    assert before[-1]["bytes"] == (KEPT - 1).to_bytes(4, "big").hex()
    assert "left out" in found[notes[0]]["summary"]
    lines = transcript.lines
    assert len(lines) == 2 * LINES + 1
    assert f"{flood - 2 * LINES} lines of the exchange left out" in lines[LINES]
    assert lines[-1].endswith(f"<- UPLINK #{flood - 1}")


def test_each_end_of_a_flow_keeps_its_bytes_and_flows_past_the_last_are_counted() -> None:
    transcript = Transcript()
    big = b"x" * 60_000
    for _ in range(KEPT):
        transcript.packet("tcp", SERVER, HARNESS, big)
    kept = [e.payload for e in transcript.entries if e.payload is not None]
    assert sum(len(p.data) for p in kept) <= 2 * KEPT_BYTES
    for port in range(FLOWS + 10):
        transcript.packet("udp", ("127.0.0.1", 20000 + port), HARNESS, b"?")
    gaps = left_out_json(transcript.entries)
    assert gaps[-1]["what"] == "flows"
    assert (gaps[-1]["count"], gaps[-1]["bytes"]) == (11, 11)  # the first is of the 64th flow
    assert gaps[-1]["source"] is None


def test_a_capture_says_where_it_left_out_and_dissects_as_a_hole() -> None:
    """The harness's requests, the server's answers of a megabyte: the capture is pcapng, a
    comment on the server's next packet says what is missing, and the dissector sees the hole
    (a note), and does not call the requests answered after it unanswered."""
    transcript = Transcript()
    sent = [0]

    def server(data: bytes) -> None:
        transcript.packet("tcp", SERVER, HARNESS, data)
        sent[0] += len(data)

    def harness(data: bytes) -> None:
        transcript.packet("tcp", HARNESS, SERVER, data)

    session = b"Session: abcdef0123456789"
    harness(b"CONNECT /site RCTP/2.0\r\nCSeq: 1\r\n\r\n")
    server(b"RCTP/2.0 200 OK\r\nCSeq: 1\r\n" + session + b";timeout=60\r\n\r\n")
    harness(b"READ /x RCTP/2.0\r\nCSeq: 2\r\n" + session + b"\r\n\r\n")
    server(b"RCTP/2.0 200 OK\r\nCSeq: 2\r\nContent-Length: %d\r\n\r\n" % (3 * KEPT * 1000))
    for _ in range(3 * KEPT):
        server(b"v" * 1000)
    harness(b"READ /x RCTP/2.0\r\nCSeq: 3\r\n" + session + b"\r\n\r\n")
    server(b"RCTP/2.0 404 Not Found\r\nCSeq: 3\r\n\r\n")
    captured = transcript.capture
    (gap,) = [item for item in captured if isinstance(item, Gap)]
    kept = sum(len(p.data) for p in captured if isinstance(p, Payload) and p.source == SERVER)
    assert (gap.source, gap.destination, gap.size) == (SERVER, HARNESS, sent[0] - kept)
    file = io.BytesIO()
    write_pcap(file, captured)
    data = file.getvalue()
    assert data[:4] == bytes.fromhex("0a0d0d0a")  # pcapng
    assert b"before this packet" in data
    payloads = [p for p in captured if isinstance(p, Payload)]
    assert sum(1 for _ in Capture(data).records()) == 3 + len(payloads)  # a handshake, and each
    findings = dissect(data, Options()).findings()
    assert len(findings) == 1, findings
    assert findings[0].startswith("note R-RCTP-13 127.0.0.1:7330")
    assert f"lost {gap.size} bytes" in findings[0]


def test_a_capture_that_left_nothing_out_is_classic_pcap() -> None:
    file = io.BytesIO()
    write_pcap(file, [Payload(1.0, "udp", HARNESS, ROBOT, b"x")])
    assert file.getvalue()[:4] == bytes.fromhex("d4c3b2a1")
