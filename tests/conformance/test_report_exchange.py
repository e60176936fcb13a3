"""A case's exchange as the JSON report holds it: each line of the transcript with the bytes of
the payload it tells of, found as the probes note them (the line first or the payload first)."""

from __future__ import annotations

from rcmlconf.conformance.reports.exchange import exchange_json
from rcmlconf.conformance.transcript import Transcript

HARNESS, SERVER, ROBOT = ("127.0.0.1", 40000), ("127.0.0.1", 7330), ("::1", 7340)


def test_lines_take_the_payload_they_tell_of_and_the_rest_stay_payloads() -> None:
    transcript = Transcript()
    transcript.note("c1 connected to 127.0.0.1:7330")
    request = b"READ /x RCTP/2.0\r\nCSeq: 2\r\n\r\n"
    transcript.sent("c1", request)  # a control probe: the line, then the payload
    transcript.packet("tcp", HARNESS, SERVER, request)
    transcript.packet("tcp", SERVER, HARNESS, b"RCTP/2.0 200 OK\r\n")  # half an answer
    transcript.packet("udp", ROBOT, HARNESS, b"\x01\x02")  # an RSP probe: the payload first
    transcript.note("[robot] <- ACK #2")
    transcript.note("[robot] -x HEARTBEAT #3 (lost by the impairment)")
    found = exchange_json(transcript.entries)
    assert [(e["direction"], e["channel"]) for e in found] == [
        ("note", "c1"),
        ("sent", "c1"),
        ("received", None),  # no line tells of it: its way is the harness's address's
        ("received", "robot"),
        ("withheld", "robot"),
    ]
    assert found[1]["bytes"] == request.hex()
    assert found[1]["summary"] == "READ /x RCTP/2.0⏎CSeq: 2⏎⏎"
    assert (found[1]["source"], found[1]["destination"]) == ("127.0.0.1:40000", "127.0.0.1:7330")
    assert found[2]["summary"] == "TCP 17 bytes"
    assert (found[3]["bytes"], found[3]["source"]) == ("0102", "[::1]:7340")
    assert found[4]["bytes"] is None
    assert all(e["time"] >= 0 for e in found)
