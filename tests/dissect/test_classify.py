"""Which protocol a flow carries (`dissect.classify`): the one rule of `rcmlconf dissect` and the
scapy layers; tests/scapy_layers/test_capture.py checks the two find the same messages."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from rcmlconf.dissect.classify import Classifier, FlowKey, Pending, parse_decode_as
from rcmlconf.errors import ProtocolError
from rcmlconf.rctp.datastream.packets import pull_packet
from rcmlconf.rsp.codec.header import pull_header

ROOT = Path(__file__).resolve().parents[2]
RSP_HELLO = bytes.fromhex(
    json.loads((ROOT / "vectors" / "rsp" / "packets.json").read_text("utf-8"))["valid"][0]["hex"]
)
DATA = bytes.fromhex(
    json.loads((ROOT / "vectors" / "rctp" / "packets.json").read_text("utf-8"))["valid"][0]["hex"]
)
A, B = b"\x0a\x00\x00\x01", b"\x0a\x00\x00\x02"


def key(sport: int, dport: int) -> FlowKey:
    return A, sport, B, dport


def test_udp_by_port_decode_as_first() -> None:
    flows = Classifier([("rsp", 7330), ("rctp-data", 9000)])
    assert flows.udp(key(5000, 7340), b"") == "rsp"  # D-RSP-9
    assert flows.udp(key(7330, 5000), b"") == "rsp"  # --decode-as before the default
    assert flows.udp(key(9000, 7340), b"") == "rctp-data"  # either end's port
    assert flows.udp(key(5000, 5001), b"") is None


def test_udp_data_endpoints_come_from_setup() -> None:
    flows = Classifier(heuristics=False)
    assert flows.udp(key(41000, 41001), DATA) is None
    assert flows.learn((B, 41001), (A, None))  # the server's port not named
    assert not flows.learn((B, 41001))  # nothing new: nothing to classify again
    assert flows.udp(key(41000, 41001), b"") == "rctp-data"
    assert flows.udp(key(41001, 41000), b"") is None  # the endpoint is B's


@pytest.mark.parametrize("payload", [DATA, RSP_HELLO, b"\x02garbage", b"\x01garbage", b"\x00"])
def test_udp_heuristics_are_the_core_codecs(payload: bytes) -> None:
    assert Classifier(heuristics=False).udp(key(5000, 5001), payload) is None
    assert Classifier().udp(key(5000, 5001), payload) == core_protocol(payload)


@given(st.binary(max_size=48))
def test_udp_heuristics_on_any_bytes(payload: bytes) -> None:
    assert Classifier().udp(key(5000, 5001), payload) == core_protocol(payload)


def core_protocol(payload: bytes) -> str | None:
    """What the core's codecs take the datagram for: the data stream's packets start with 2, RSP's
    with 1 (D-RCTP-19, D-RSP-10)."""
    try:
        if payload[:1] == b"\x02":
            pull_packet(payload)
            return "rctp-data"
        if payload[:1] == b"\x01":
            pull_header(payload)
            return "rsp"
    except ProtocolError:
        pass
    return None


def test_tcp_by_port_notes_the_server() -> None:
    flows = Classifier([("rctp", 8000)])
    assert flows.tcp(key(40000, 8000)) is True
    assert flows.tcp(key(7330, 40001)) is True
    assert flows.servers == {(B, 8000), (A, 7330)}
    assert flows.tcp(key(40002, 9000)) is None  # its first bytes are to tell
    assert Classifier(heuristics=False).tcp(key(40002, 9000)) is False


def test_a_held_connection_is_rctp_by_a_start_line() -> None:
    flows = Classifier()
    first = key(40000, 9000)
    pending: Pending[int] = Pending(first)
    assert flows.look(pending, 0, 1, b"CONN") is None  # not yet a line
    assert flows.look(pending, 0, 2, b"ECT /robot RCTP/2.0\r\n") is True
    assert pending.segments == [1, 2]
    assert flows.servers == {(B, 9000)}  # the side that sent a request is a client
    assert flows.tcp(key(40001, 9000)) is True  # later connections to it are RCTP


def test_a_held_connection_answered_by_a_status_line_notes_no_server() -> None:
    flows = Classifier()
    pending: Pending[int] = Pending(key(40000, 9000))
    assert flows.look(pending, 1, 1, b"RCTP/2.0 200 OK\r\n") is True
    assert flows.servers == set()


@pytest.mark.parametrize(
    ("payload", "segments"), [(b"GET / HTTP/1.1\r\n", 1), (b"\x00" * 16, 1), (b"", 33)]
)
def test_a_held_connection_that_is_not_rctp(payload: bytes, segments: int) -> None:
    """A line that is no start line, 16 bytes without one, or 33 segments without either (bare
    ACKs): held no longer."""
    flows = Classifier()
    pending: Pending[int] = Pending(key(40000, 9000))
    decided = [flows.look(pending, 0, n, payload) for n in range(segments)]
    assert decided[-1] is False
    assert decided[:-1] == [None] * (segments - 1)


@pytest.mark.parametrize("text", ["rsp", "http=80", "rsp=0", "rsp=70000", "rctp=x", "data=1"])
def test_a_bad_decode_as_is_refused(text: str) -> None:
    with pytest.raises(ValueError, match=r"PROTO=PORT|port"):
        parse_decode_as(text)


def test_decode_as() -> None:
    assert parse_decode_as(" RCTP-Data=41000") == ("rctp-data", 41000)
