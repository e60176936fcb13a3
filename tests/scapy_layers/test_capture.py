"""Captures read through the layers: scapy's own TCPSession (tcp_reassemble) and `capture`
(`rcmlconf dissect -V`), against the core reader on the same bytes.

The pcaps are made with rcmlconf.pcap.writer (LINKTYPE_RAW, a handshake per connection, segments
of at most 1,460 bytes); each `write` of a slice of a message is one more segment.
"""

from __future__ import annotations

import itertools
import json
import struct
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given
from hypothesis import strategies as st
from scapy.layers.inet import IP, TCP, UDP, fragment
from scapy.layers.l2 import Ether
from scapy.packet import Packet, Padding, Raw
from scapy.sendrecv import sniff
from scapy.sessions import TCPSession
from scapy.utils import PcapNgWriter, wrpcap
from support.pcaps import TCP_ACK, TCP_FIN, TCP_SYN, epb, idb, ipv4_tcp, pcap, shb
from support.rsp_models import robot_model
from support.scapy_layers import core_messages, layer_message

from rcmlconf.dissect import Dissector, Options, Record
from rcmlconf.pcap.reader import Capture
from rcmlconf.pcap.records import CaptureError
from rcmlconf.pcap.writer import Payload, PcapWriter
from rcmlconf.scapy_layers import capture, rctp, rsp

ROOT = Path(__file__).resolve().parents[2]
RSP_VECTORS = json.loads((ROOT / "vectors" / "rsp" / "packets.json").read_text("utf-8"))
RCTP_VECTORS = json.loads((ROOT / "vectors" / "rctp" / "packets.json").read_text("utf-8"))
CUBO = robot_model()
CAPTURES = sorted((ROOT / "captures").glob("*.pcap"))

CLIENT = ("10.0.0.1", 40100)
SERVER = ("10.0.0.2", 7330)
DATA_PORT = 41000

CONNECT = b"CONNECT /testbot RCTP/2.0\r\nCSeq: 1\r\nUser-Agent: rcmlconf/0.1\r\n\r\n"
CONNECTED = b"RCTP/2.0 200 OK\r\nCSeq: 1\r\nSession: abcdefgh1234;timeout=60\r\n\r\n"
SETUP = (
    b"SETUP /drive/wheels RCTP/2.0\r\nCSeq: 2\r\nSession: abcdefgh1234\r\n"
    b"Transport: udp;client_port=41001;mode=read\r\n\r\n"
)
SET_UP = (
    b"RCTP/2.0 200 OK\r\nCSeq: 2\r\nSession: abcdefgh1234\r\nTransport: udp;client_port=41001;"
    b"mode=read;server_port=41000;tag=a3f19c07;stream=1\r\n\r\n"
)
LARGE = b"\x01" * 3000
WRITE = (
    b"WRITE /head/control/lcd RCTP/2.0\r\nCSeq: 3\r\nSession: abcdefgh1234\r\n"
    b"Content-Type: application/rctp-values\r\nContent-Length: %d\r\n\r\n" % len(LARGE) + LARGE
)
OK = b"RCTP/2.0 200 OK\r\nCSeq: %d\r\nSession: abcdefgh1234\r\n\r\n"
READS = b"".join(
    b"READ /head/control/tilt RCTP/2.0\r\nCSeq: %d\r\nSession: abcdefgh1234\r\n\r\n" % n
    for n in (4, 5, 6)
)
SERVER_WRITE = (
    b"WRITE /drive/settings RCTP/2.0\r\nCSeq: 1\r\nSession: abcdefgh1234\r\nNodes: enabled\r\n"
    b"Content-Type: application/rctp-values\r\nContent-Length: 1\r\n\r\n\x01"
)


def rsp_vector(name: str) -> bytes:
    return bytes.fromhex(next(v["hex"] for v in RSP_VECTORS["valid"] if v["name"] == name))


def rctp_vector(name: str) -> bytes:
    return bytes.fromhex(next(v["hex"] for v in RCTP_VECTORS["valid"] if v["name"] == name))


def pieces(data: bytes, *cuts: int) -> list[bytes]:
    edges = [0, *cuts, len(data)]
    return [data[a:b] for a, b in itertools.pairwise(edges)]


#: (from the client?, the bytes of one write): the session as the two sides wrote it.
CONVERSATION: list[tuple[bool, bytes]] = [
    # a request cut into four segments
    *((True, part) for part in pieces(CONNECT, 3, 20, 21)),
    (False, CONNECTED),
    (True, SETUP),
    (False, SET_UP),
    # a body of 3,000 bytes: its head in one segment, the body over three (MSS 1,460)
    *((True, part) for part in pieces(WRITE, 50, 150)),
    (False, OK % 3),
    # three requests in one segment, and the answers
    (True, READS),
    (False, (OK % 4) + (OK % 5) + (OK % 6)[:10]),
    (False, (OK % 6)[10:]),
    # the server asks, the client answers: requests go both ways (D-RCTP-5)
    (False, SERVER_WRITE[:30]),
    (False, SERVER_WRITE[30:] + b"BYE * RCTP/2.0\r\nCSeq: 2\r\nSession: abc"),
    (True, OK % 1),
    (False, b"defgh1234\r\nReason: shutdown\r\n\r\n"),
]


def write_session(path: Path) -> None:
    """The conversation, with RSP and data-stream datagrams in between."""
    with path.open("wb") as file:
        writer = PcapWriter(file)
        at = 1_700_000_000.0
        for number, (from_client, data) in enumerate(CONVERSATION):
            source, destination = (CLIENT, SERVER) if from_client else (SERVER, CLIENT)
            writer.write(Payload(at, "tcp", source, destination, data))
            at += 0.01
            if number == 6:  # after SETUP's answer: the data stream on its negotiated ports
                stream = rctp_vector("four-payloads")
                writer.write(Payload(at, "udp", ("10.0.0.2", DATA_PORT), CLIENT, stream))
                writer.write(Payload(at, "udp", ("10.0.0.1", 41001), ("10.0.0.2", 9), stream))
            if number == 9:
                rsp_packet = rsp_vector("downlink-typical")
                writer.write(
                    Payload(at, "udp", ("10.0.0.1", 50000), ("10.0.0.2", 7340), rsp_packet)
                )


@pytest.fixture(scope="module")
def session_pcap(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("captures") / "session.pcap"
    write_session(path)
    return path


def direction_bytes(from_client: bool) -> bytes:
    return b"".join(data for client, data in CONVERSATION if client is from_client)


def expected_messages() -> dict[bool, list[dict[str, Any]]]:
    """What the core reader frames in each direction."""
    expected = {}
    for from_client in (True, False):
        found, stopped = core_messages(direction_bytes(from_client))
        assert stopped is None
        expected[from_client] = found
    return expected


def chained(layer: Packet) -> Iterator[Packet]:
    while layer and not isinstance(layer, Raw | Padding):
        yield layer
        layer = layer.payload


def test_tcp_session_reassembles_split_and_pipelined_messages(session_pcap: Path) -> None:
    """scapy's own TCPSession with the layer's tcp_reassemble (R-RCTP-13)."""
    found: dict[bool, list[dict[str, Any]]] = {True: [], False: []}
    for packet in sniff(offline=str(session_pcap), session=TCPSession):
        if TCP in packet and packet[TCP].payload:
            assert isinstance(packet[TCP].payload, rctp.RCTPRequest | rctp.RCTPResponse)
            from_client = packet[TCP].sport == CLIENT[1]
            found[from_client].extend(layer_message(m) for m in chained(packet[TCP].payload))
    expected = expected_messages()
    assert found == expected
    assert len(expected[True]) == 7  # CONNECT, SETUP, WRITE, three READs, the 200
    assert len(expected[False]) == 8  # five 200s, WRITE and BYE from the server
    assert expected[True][2]["body"] == LARGE


def test_capture_messages_are_the_core_messages_in_order(session_pcap: Path) -> None:
    found: dict[bool, list[dict[str, Any]]] = {True: [], False: []}
    udp = []
    for message in capture.messages(session_pcap):
        if message.protocol == "rctp":
            found[message.source == CLIENT].append(layer_message(message.packet))
        else:
            udp.append(message)
    assert found == expected_messages()
    # The data stream is on the ports SETUP's answer gave (D-RCTP-18), RSP on 7340.
    assert [(m.protocol, m.source[1], m.destination[1]) for m in udp] == [
        ("rctp-data", DATA_PORT, CLIENT[1]),
        ("rctp-data", 41001, 9),
        ("rsp", 50000, 7340),
    ]
    assert isinstance(udp[0].packet, rctp.RCTPStream)
    assert len(udp[0].packet.payloads) == 4


def test_a_message_is_given_with_the_frame_that_completed_it(session_pcap: Path) -> None:
    found = list(capture.messages(session_pcap))
    connect = found[0]
    # three handshake segments, then CONNECT in four: the fourth completes it
    assert connect.frame == 7
    assert connect.packet.method == b"CONNECT"
    assert connect.time == pytest.approx(1_700_000_000.0)
    assert [m.frame for m in found] == sorted(m.frame for m in found)


def test_detail_is_show_dump_of_each_message(session_pcap: Path) -> None:
    texts = list(capture.detail(session_pcap, model=CUBO))
    messages = list(capture.messages(session_pcap, model=CUBO))
    assert len(texts) == len(messages) == 18
    before = rsp.use_model(CUBO)
    try:
        for text, message in zip(texts, messages, strict=True):
            assert text == message.packet.show(dump=True)
            assert text == capture.render(message.packet)
    finally:
        rsp.use_model(before)
    rsp_text = next(t for t in texts if "RSP DOWNLINK" in t)
    assert "leftWheel: speed=120" in rsp_text
    assert "Transport: udp;client_port=41001;mode=read;server_port=41000" in texts[3]


def test_detail_without_a_model_keeps_map_bodies_raw(session_pcap: Path) -> None:
    texts = list(capture.detail(session_pcap))
    rsp_text = next(t for t in texts if "RSP DOWNLINK" in t)
    assert "###[ Raw ]###" in rsp_text
    assert "device_map" not in rsp_text


def test_the_model_in_use_is_set_back_after_reading(session_pcap: Path) -> None:
    before = rsp.use_model(None)
    try:
        list(capture.messages(session_pcap, model=CUBO))
        assert rsp.current_model() is None
    finally:
        rsp.use_model(before)


def test_render_is_show_dump_for_every_vector() -> None:
    before = rsp.use_model(CUBO)
    try:
        for vector in RSP_VECTORS["valid"] + RSP_VECTORS["malformed"]:
            if vector["model"] != "CUBO":
                continue
            packet = rsp.RSP(bytes.fromhex(vector["hex"]))
            assert capture.render(packet) == packet.show(dump=True), vector["name"]
    finally:
        rsp.use_model(before)
    for vector in RCTP_VECTORS["valid"] + RCTP_VECTORS["malformed"]:
        packet = rctp.RCTPStream(bytes.fromhex(vector["hex"]))
        assert capture.render(packet) == packet.show(dump=True), vector["name"]


def test_decode_as_names_other_ports(tmp_path: Path) -> None:
    path = tmp_path / "ports.pcap"
    with path.open("wb") as file:
        writer = PcapWriter(file)
        writer.write(
            Payload(1.0, "udp", ("10.0.0.1", 5000), ("10.0.0.2", 9000), rsp_vector("hello"))
        )
        writer.write(Payload(2.0, "tcp", ("10.0.0.1", 5001), ("10.0.0.2", 8000), CONNECT))
        writer.write(
            Payload(3.0, "udp", ("10.0.0.1", 5002), ("10.0.0.2", 8000), rctp_vector("sequence-0"))
        )
    assert list(capture.messages(path, heuristics=False)) == []
    chosen = ["rsp=9000", ("rctp", 8000), "rctp-data=8000"]
    found = list(capture.messages(path, decode_as=chosen, heuristics=False))
    assert [m.protocol for m in found] == ["rsp", "rctp", "rctp-data"]
    assert isinstance(found[0].packet.payload, rsp.RSPHello)
    assert found[1].packet.method == b"CONNECT"


def test_heuristics_find_our_protocols_on_other_ports(tmp_path: Path) -> None:
    """As `rcmlconf dissect` does: a valid RSP header, a data-stream packet whose framing holds,
    a connection whose first bytes are an RCTP start line; and later connections to that
    server, whatever they start with."""
    path = tmp_path / "heuristics.pcap"
    server = ("10.0.0.2", 8000)
    with path.open("wb") as file:
        writer = PcapWriter(file)
        writer.write(
            Payload(1.0, "udp", ("10.0.0.1", 5000), ("10.0.0.2", 9000), rsp_vector("hello"))
        )
        writer.write(Payload(1.1, "udp", ("10.0.0.1", 5000), ("10.0.0.2", 9001), b"\x01 not RSP"))
        writer.write(
            Payload(1.2, "udp", ("10.0.0.1", 5002), ("10.0.0.2", 9002), rctp_vector("sequence-0"))
        )
        writer.write(Payload(2.0, "tcp", ("10.0.0.1", 5001), server, CONNECT))
        writer.write(Payload(2.1, "tcp", server, ("10.0.0.1", 5001), CONNECTED))
        writer.write(
            Payload(3.0, "tcp", ("10.0.0.1", 5003), ("10.0.0.2", 80), b"GET / HTTP/1.1\r\n")
        )
        # a second connection to the server: its first bytes come from the server
        writer.write(Payload(4.0, "tcp", server, ("10.0.0.1", 5004), b"\x00" * 20))
    found = list(capture.messages(path))
    assert [(m.protocol, m.destination[1]) for m in found] == [
        ("rsp", 9000),
        ("rctp-data", 9002),
        ("rctp", 8000),
        ("rctp", 5001),
        ("rctp", 5004),
    ]
    assert isinstance(found[-1].packet, Raw)


def test_data_stream_endpoints_come_from_setup(tmp_path: Path) -> None:
    """Only the endpoints SETUP's 200 named are the data stream's (D-RCTP-18)."""
    path = tmp_path / "setup.pcap"
    stream = rctp_vector("sequence-0")
    with path.open("wb") as file:
        writer = PcapWriter(file)
        writer.write(Payload(0.5, "udp", ("10.0.0.2", 41000), CLIENT, stream))  # before SETUP
        writer.write(Payload(1.0, "tcp", CLIENT, SERVER, SETUP))
        writer.write(Payload(2.0, "tcp", SERVER, CLIENT, SET_UP))
        writer.write(Payload(3.0, "udp", ("10.0.0.2", 41000), CLIENT, stream))
        writer.write(Payload(3.1, "udp", ("10.0.0.1", 41001), ("10.0.0.2", 41000), stream))
        writer.write(Payload(3.2, "udp", ("10.0.0.9", 41000), ("10.0.0.8", 4), stream))
    found = list(capture.messages(path, heuristics=False))
    assert [(m.protocol, m.time) for m in found] == [
        ("rctp", 1.0),
        ("rctp", 2.0),
        ("rctp-data", 3.0),
        ("rctp-data", 3.1),
    ]


def mixed_capture(path: Path) -> Path:
    """Our protocols on other ports, found by their look; a data stream SETUP's answer names, seen
    first before the SETUP; a SETUP answered without a tag (no endpoint learnt); a server seen
    speaking RCTP, whose later connection starts with bytes of no message; traffic of others."""
    server = ("10.0.0.2", 8000)
    no_tag = (
        b"RCTP/2.0 200 OK\r\nCSeq: 3\r\nSession: abcdefgh1234\r\nTransport: udp;"
        b"client_port=42001;mode=read;server_port=42000\r\n\r\n"
    )
    stream = rctp_vector("sequence-0")
    sent: list[tuple[str, tuple[str, int], tuple[str, int], bytes]] = [
        ("udp", ("10.0.0.1", 5000), ("10.0.0.2", 9000), rsp_vector("hello")),
        ("udp", ("10.0.0.1", 5000), ("10.0.0.2", 9001), b"\x01 not RSP"),
        ("udp", ("10.0.0.1", 5002), ("10.0.0.2", 9002), stream),
        ("udp", ("10.0.0.2", 41000), ("10.0.0.1", 41001), b"before SETUP"),
        ("udp", ("10.0.0.2", 42000), ("10.0.0.1", 42001), b"never named"),
        ("tcp", CLIENT, server, CONNECT),
        ("tcp", server, CLIENT, CONNECTED),
        ("tcp", CLIENT, server, SETUP),
        ("tcp", server, CLIENT, SET_UP.replace(b"client_port=41001;", b"")),
        ("udp", ("10.0.0.2", 41000), ("10.0.0.1", 41001), stream),
        ("udp", ("10.0.0.1", 41001), ("10.0.0.2", 41000), stream),
        ("tcp", CLIENT, server, SETUP.replace(b"41001", b"42001")),
        ("tcp", server, CLIENT, no_tag),
        ("udp", ("10.0.0.2", 42000), ("10.0.0.1", 42001), stream),
        ("tcp", ("10.0.0.1", 5003), ("10.0.0.2", 80), b"GET / HTTP/1.1\r\n"),
        ("tcp", server, ("10.0.0.1", 5004), b"\x00" * 20),
        ("tcp", ("10.0.0.1", 5005), ("10.0.0.2", 81), b"STOP /x RCTP/2.0\r\n\r\n"),
        ("udp", ("10.0.0.1", 7777), ("10.0.0.2", 7340), b"\x02 on RSP's port"),
    ]
    with path.open("wb") as file:
        writer = PcapWriter(file)
        for index, (protocol, source, destination, data) in enumerate(sent):
            writer.write(Payload(1.0 + index / 100, protocol, source, destination, data))
    return path


@pytest.mark.parametrize(
    ("decode_as", "heuristics"),
    [
        ((), True),
        ((), False),
        ((("rsp", 9001),), True),
        ((("rctp", 8000),), False),
        ((("rctp", 81), ("rsp", 42000)), False),
    ],
)
def test_the_flows_are_rcmlconf_dissects(
    tmp_path: Path, decode_as: tuple[tuple[str, int], ...], heuristics: bool
) -> None:
    """One rule (`dissect.classify`) for both: the same datagrams taken as the same protocol,
    the same connections taken as RCTP (how each shows bytes of no message may differ)."""
    path = mixed_capture(tmp_path / "mixed.pcap")
    records: list[Record] = []
    with Capture.open(path) as opened:
        analysis = Dissector(
            Options(decode_as=decode_as, heuristics=heuristics), records.append
        ).run(opened)
    found = list(capture.messages(path, decode_as=decode_as, heuristics=heuristics))

    def text(address: tuple[str, int]) -> str:
        return f"{address[0]}:{address[1]}"

    datagrams = [
        (m.protocol, text(m.source), text(m.destination)) for m in found if m.protocol != "rctp"
    ]
    assert datagrams == [
        (r.protocol, r.source, r.destination) for r in records if r.protocol != "rctp"
    ]
    connections = {
        frozenset((text(m.source), text(m.destination))) for m in found if m.protocol == "rctp"
    }
    assert connections == {frozenset((c.client, c.server)) for c in analysis.control}
    assert datagrams  # the capture has something to find either way


@pytest.mark.parametrize("text", ["rsp", "http=80", "rsp=0", "rsp=70000", "rctp=x", "data=1"])
def test_a_bad_decode_as_is_refused(text: str) -> None:
    with pytest.raises(ValueError, match=r"PROTO=PORT|port"):
        capture.parse_decode_as(text)


def ip_packets() -> list[Packet]:
    return [
        IP(src="10.0.0.1", dst="10.0.0.2") / UDP(sport=5000, dport=7340) / rsp_vector("hello"),
        IP(src="10.0.0.1", dst="10.0.0.2")
        / TCP(sport=5001, dport=7330, flags="PA", seq=100)
        / CONNECT,
    ]


def test_link_types_and_pcapng(tmp_path: Path) -> None:
    """Ethernet (with a VLAN tag), Linux cooked capture, BSD loopback and pcapng."""
    from scapy.layers.l2 import CookedLinux, Dot1Q, Loopback

    variants = {
        "ether.pcap": [Ether() / Dot1Q(vlan=5) / p for p in ip_packets()],
        "sll.pcap": [CookedLinux(proto=0x0800) / p for p in ip_packets()],
        "null.pcap": [Loopback(type=2) / p for p in ip_packets()],
    }
    for name, frames in variants.items():
        wrpcap(str(tmp_path / name), frames)
    writer = PcapNgWriter(str(tmp_path / "ether.pcapng"))
    for frame in variants["ether.pcap"]:
        writer.write(frame)
    writer.close()
    for name in [*variants, "ether.pcapng"]:
        found = list(capture.messages(tmp_path / name))
        assert [m.protocol for m in found] == ["rsp", "rctp"], name
        assert found[1].packet.method == b"CONNECT", name


#: An RSP packet above the MTU: a DOWNLINK with an LCD image.
IMAGE = bytes(range(256)) * 8
LCD = (
    struct.pack(">BHBBHIHIHB", 1, 1, 0, 4, 7, 140, 0xA1B2, 0xC3D4E5F6, 6, 0)
    + b"\x00\x90\x00\x00"  # the Device Map: head, lcd
    + len(IMAGE).to_bytes(2, "big")
    + IMAGE
)


def test_ip_fragments_are_put_back_together(tmp_path: Path) -> None:
    """An RSP packet above the MTU arrives in IPv4 fragments, or IPv6 ones, in any order, some
    sent again in other sizes."""
    from scapy.layers.inet6 import IPv6, IPv6ExtHdrFragment, fragment6

    datagram = IP(src="10.0.0.1", dst="10.0.0.2", id=77) / UDP(sport=5000, dport=7340) / LCD
    parts = fragment(datagram, fragsize=600)
    assert len(parts) > 3
    overlapping = [*parts[:2], *fragment(datagram, fragsize=808)[1:]]
    v6 = (
        IPv6(src="fe80::1", dst="fe80::2")
        / IPv6ExtHdrFragment(id=5)
        / UDP(sport=5000, dport=7340)
        / LCD
    )
    wrpcap(str(tmp_path / "v4.pcap"), list(reversed(parts)) + overlapping)
    wrpcap(str(tmp_path / "v6.pcap"), fragment6(v6, 1280))
    found = [
        *capture.messages(tmp_path / "v4.pcap", model=CUBO),
        *capture.messages(tmp_path / "v6.pcap", model=CUBO),
    ]
    assert len(found) == 3
    for message in found:
        items = message.packet.payload.payloads
        assert [item.device for item in items] == ["head", "lcd"]
        assert items[1].values == {"image": IMAGE}


def test_segments_out_of_order_and_retransmitted_are_read_once(tmp_path: Path) -> None:
    one = b"READ /a RCTP/2.0\r\nCSeq: 1\r\n\r\n"
    two = b"READ /b RCTP/2.0\r\nCSeq: 2\r\n\r\n"
    data = one + two

    def segment(seq: int, payload: bytes, flags: str = "PA") -> Packet:
        return (
            IP(src="10.0.0.1", dst="10.0.0.2")
            / TCP(sport=5001, dport=7330, flags=flags, seq=seq)
            / payload
        )

    frames = [
        IP(src="10.0.0.1", dst="10.0.0.2") / TCP(sport=5001, dport=7330, flags="S", seq=999),
        segment(1000 + 20, data[20:40]),  # ahead of a hole
        segment(1000, data[:20]),  # fills it
        segment(1000, data[:25]),  # a retransmission
        segment(1000 + 40, data[40:]),
        segment(1000 + len(data), b"", "FA"),
    ]
    wrpcap(str(tmp_path / "order.pcap"), frames)
    found = [m.packet for m in capture.messages(tmp_path / "order.pcap")]
    assert [bytes(p) for p in found] == [one, two]


READ = b"READ /a RCTP/2.0\r\nCSeq: %d\r\n\r\n"


def client_segments(path: Path, *segments: tuple[int, int, bytes]) -> list[capture.Message]:
    """The messages of a capture of the client's SYN (sequence number 999), then `segments`:
    (sequence number, TCP flags, payload), one frame each."""
    frames = [(1.0, ipv4_tcp(CLIENT, SERVER, 999, TCP_SYN, b""))]
    frames += [(2.0 + n, ipv4_tcp(CLIENT, SERVER, *segment)) for n, segment in enumerate(segments)]
    path.write_bytes(pcap(frames))
    return list(capture.messages(path))


def test_segments_overlapping_what_waits_are_read_once(tmp_path: Path) -> None:
    data = READ % 1 + READ % 2 + READ % 3
    found = client_segments(
        tmp_path / "overlap.pcap",
        (1020, TCP_ACK, data[20:60]),  # ahead of a hole
        (1020, TCP_ACK, data[20:40]),  # a shorter copy of what waits
        (1000, TCP_ACK, data[:30]),  # ends inside what waits
        (1060, TCP_ACK | TCP_FIN, data[60:]),
    )
    assert [bytes(m.packet) for m in found] == [READ % 1, READ % 2, READ % 3]
    assert [m.frame for m in found] == [4, 4, 5]


def test_a_new_connection_between_the_same_ports(tmp_path: Path) -> None:
    """A SYN that is not the connection's own again opens a new one; a segment sent again after
    the FIN is not a message again."""
    first = READ % 1 + (READ % 2)[:10]
    found = client_segments(
        tmp_path / "again.pcap",
        (1000, TCP_ACK, first),
        (1000 + len(first), TCP_ACK | TCP_FIN, b""),
        (1000, TCP_ACK, READ % 1),  # sent again after the FIN
        (999, TCP_SYN, b""),  # the first SYN again: nothing new
        (70000, TCP_SYN, b""),
        (70001, TCP_ACK, READ % 1),
    )
    assert [(m.frame, bytes(m.packet)) for m in found] == [
        (2, READ % 1),
        (3, (READ % 2)[:10]),  # cut short by the FIN
        (7, READ % 1),
    ]


def test_what_follows_a_hole_the_capture_never_fills(tmp_path: Path) -> None:
    """A segment the capture lost: the message it cut is shown cut short, and what follows comes
    out at the end of the capture, or once 64 segments wait behind the hole (`sniff` prints
    as frames come)."""
    one, two = READ % 1, READ % 2
    found = client_segments(
        tmp_path / "hole.pcap",
        (1000, TCP_ACK, one + two[:10]),
        (1000 + len(one) + 20, TCP_ACK, two[20:]),  # after 10 bytes the capture lost
        (1000 + len(one + two), TCP_ACK, READ % 3),
    )
    assert [(m.frame, bytes(m.packet)) for m in found] == [
        (2, one),
        (4, two[:10]),
        (4, two[20:] + READ % 3),  # starts inside a message: it cannot be framed
    ]
    assert isinstance(found[2].packet, Raw)
    later = [READ % n for n in range(3, 73)]
    starts = list(itertools.accumulate(map(len, later), initial=1000 + len(one + two)))
    found = client_segments(
        tmp_path / "long.pcap",
        (1000, TCP_ACK, one),
        *((start, TCP_ACK, data) for start, data in zip(starts, later, strict=False)),
    )
    assert [bytes(m.packet) for m in found] == [one, *later]
    # frame 2 is the first segment, 3 to 67 the 65 behind the hole: the 65th gives it up
    assert [m.frame for m in found[1:66]] == [67] * 65
    assert [m.frame for m in found[66:]] == [68, 69, 70, 71, 72]


def test_data_on_a_syn_is_read(tmp_path: Path) -> None:
    """TCP Fast Open (RFC 7413): the first request rides on the SYN."""
    path = tmp_path / "fast-open.pcap"
    path.write_bytes(
        pcap(
            [
                (1.0, ipv4_tcp(CLIENT, SERVER, 999, TCP_SYN, READ % 1)),
                (2.0, ipv4_tcp(CLIENT, SERVER, 1000 + len(READ % 1), TCP_ACK, READ % 2)),
            ]
        )
    )
    assert [bytes(m.packet) for m in capture.messages(path)] == [READ % 1, READ % 2]


@pytest.mark.parametrize("path", CAPTURES, ids=lambda path: path.name)
def test_a_pcapng_of_a_capture_reads_as_the_pcap(path: Path, tmp_path: Path) -> None:
    """The same records in a pcapng file (nanosecond stamps): the same messages, in the same
    frames, with the same summary lines and field trees."""
    with Capture.open(path) as opened:
        records = list(opened.frames())
    copy = tmp_path / f"{path.stem}.pcapng"
    blocks = [epb(0, round(time * 1e9), frame) for time, _, frame in records]
    copy.write_bytes(shb() + idb(records[0][1], tsresol=9) + b"".join(blocks))

    def shown(file: Path) -> list[tuple[int, str, str]]:
        found = capture.messages(file, model=CUBO)
        return [(m.frame, capture.summary(m), capture.render(m.packet)) for m in found]

    assert shown(copy) == shown(path)


def test_a_capture_that_breaks_is_read_up_to_there(session_pcap: Path, tmp_path: Path) -> None:
    """As `rcmlconf dissect` reads it: the messages before the broken record, what the
    connections left unfinished, then the error."""
    broken = tmp_path / "broken.pcap"
    broken.write_bytes(session_pcap.read_bytes()[:-10])
    whole = list(capture.messages(session_pcap))
    found: list[capture.Message] = []
    with pytest.raises(CaptureError, match="runs past the end of the file"):
        found.extend(capture.messages(broken))
    assert found[:-1] == whole[:-1]
    # the last record completed the server's BYE: cut short without it
    assert whole[-1].packet.method == b"BYE"
    assert bytes(found[-1].packet) == bytes(whole[-1].packet)[: len(bytes(found[-1].packet))]
    assert len(bytes(found[-1].packet)) < len(bytes(whole[-1].packet))


def test_bytes_that_cannot_be_framed_are_one_raw_message(tmp_path: Path) -> None:
    path = tmp_path / "garbage.pcap"
    with path.open("wb") as file:
        writer = PcapWriter(file)
        writer.write(Payload(1.0, "tcp", CLIENT, SERVER, b"\x16\x03\x01\x02\x00 TLS hello"))
        writer.write(Payload(2.0, "tcp", SERVER, CLIENT, b"RCTP/2.0 200 OK\r\nCSeq: 1\r\n"))
    found = list(capture.messages(path))
    assert isinstance(found[0].packet, Raw)
    assert capture.summary(found[0]).endswith("RCTP cannot be framed (15 bytes)")
    # a head the capture ended before completing
    assert found[1].frame == 5
    assert isinstance(found[1].packet, Raw)


def test_summary_line(session_pcap: Path) -> None:
    lines = [capture.summary(m) for m in capture.messages(session_pcap, model=CUBO)]
    assert lines[0].endswith("10.0.0.1:40100 -> 10.0.0.2:7330 RCTP CONNECT /testbot CSeq=1")
    assert any("RCTP-data seq=4660 tag=a3f19c07 DATA s1 32B" in line for line in lines)
    assert any("RSP DOWNLINK seq=1042" in line and "irFire#3" in line for line in lines)
    assert any("RCTP WRITE /head/control/lcd CSeq=3 (3000 bytes)" in line for line in lines)


def test_ipv6_endpoints(tmp_path: Path) -> None:
    from scapy.layers.inet6 import IPv6, IPv6ExtHdrDestOpt

    frames = [
        Ether()
        / IPv6(src="fe80::1", dst="fe80::2")
        / UDP(sport=5000, dport=7340)
        / rsp_vector("hello"),
        Ether()
        / IPv6(src="fe80::1", dst="fe80::2")
        / IPv6ExtHdrDestOpt()
        / TCP(sport=5001, dport=7330, flags="PA", seq=1)
        / CONNECT,
    ]
    wrpcap(str(tmp_path / "v6.pcap"), frames)
    found = list(capture.messages(tmp_path / "v6.pcap"))
    assert [(m.protocol, m.source) for m in found] == [
        ("rsp", ("fe80::1", 5000)),
        ("rctp", ("fe80::1", 5001)),
    ]
    assert " [fe80::1]:5001 -> [fe80::2]:7330 RCTP CONNECT" in capture.summary(found[1])


@given(st.sampled_from([1, 101, 113, 0, 276, 228]), st.binary(max_size=120))
def test_any_frame_is_read_without_raising(linktype: int, frame: bytes) -> None:
    dissector = capture.Dissector()
    for message in dissector.frame(1, 0.0, linktype, frame):
        capture.render(message.packet)
        capture.summary(message)
    dissector.finish()


@given(st.binary(min_size=1, max_size=80), st.sampled_from([6, 17]))
def test_any_transport_payload_is_read_without_raising(payload: bytes, protocol: int) -> None:
    """An IPv4 packet to a port of ours with any bytes after its header."""
    frame = (
        bytes(
            IP(src="10.0.0.1", dst="10.0.0.2", proto=protocol)
            / (UDP(sport=1, dport=7340) if protocol == 17 else TCP(sport=1, dport=7330, seq=5))
        )
        + payload
    )
    dissector = capture.Dissector()
    for message in [*dissector.frame(1, 0.0, 101, frame), *dissector.finish()]:
        capture.render(message.packet)


def test_bind_port_in_a_scapy_session(tmp_path: Path) -> None:
    """A scapy user decodes other ports with bind_port, as contrib layers do."""
    from scapy.layers.inet import TCP as ScapyTCP
    from scapy.packet import split_bottom_up
    from scapy.utils import rdpcap

    path = tmp_path / "other.pcap"
    with path.open("wb") as file:
        writer = PcapWriter(file)
        writer.write(
            Payload(1.0, "udp", ("10.0.0.1", 5000), ("10.0.0.2", 9100), rsp_vector("hello"))
        )
        writer.write(Payload(2.0, "tcp", ("10.0.0.1", 5001), ("10.0.0.2", 9101), CONNECT))
    rsp.bind_port(9100)
    rctp.bind_port(9101)
    try:
        packets = rdpcap(str(path))
        assert rsp.RSPHello in packets[0]
        assert packets[-1][rctp.RCTPRequest].method == b"CONNECT"
    finally:
        split_bottom_up(UDP, rsp.RSP, sport=9100)
        split_bottom_up(UDP, rsp.RSP, dport=9100)
        for key in ("sport", "dport"):
            split_bottom_up(ScapyTCP, rctp.RCTP, **{key: 9101})
            split_bottom_up(UDP, rctp.RCTPStream, **{key: 9101})
