"""rcmlconf.pcap.frames: link layers, IPv4 and IPv6 (their fragments put together), TCP and UDP;
broken headers are a FrameError at their offset, and nothing else escapes."""

from __future__ import annotations

import struct

import pytest
from hypothesis import given
from hypothesis import strategies as st
from support.pcaps import ethernet, ipv4, ipv4_tcp, ipv4_udp, ipv6_udp, null, sll, sll2

from rcmlconf.pcap.addresses import address_text, endpoint_text
from rcmlconf.pcap.frames import (
    LINK_TYPES,
    LINKTYPE_ETHERNET,
    LINKTYPE_IPV6,
    LINKTYPE_LINUX_SLL,
    LINKTYPE_LINUX_SLL2,
    LINKTYPE_LOOP,
    LINKTYPE_NULL,
    LINKTYPE_RAW,
    UDP,
    FrameDecoder,
)
from rcmlconf.pcap.records import FrameError

A, B = ("10.0.0.2", 50000), ("10.0.0.7", 7340)
DATAGRAM = ipv4_udp(A, B, b"hello")
V6A = bytes.fromhex("20010db8000000000000000000000001")
V6B = bytes.fromhex("20010db8000000000000000000000002")


@pytest.mark.parametrize(
    ("linktype", "frame"),
    [
        (LINKTYPE_RAW, DATAGRAM),
        (LINKTYPE_ETHERNET, ethernet(DATAGRAM)),
        (LINKTYPE_ETHERNET, ethernet(DATAGRAM, vlan=7)),
        (LINKTYPE_LINUX_SLL, sll(DATAGRAM)),
        (LINKTYPE_LINUX_SLL2, sll2(DATAGRAM)),
        (LINKTYPE_NULL, null(DATAGRAM, "<")),
        (LINKTYPE_NULL, null(DATAGRAM, ">")),
        (LINKTYPE_LOOP, null(DATAGRAM, ">")),
        (12, DATAGRAM),  # DLT_RAW of older files
        (14, DATAGRAM),  # DLT_RAW of OpenBSD's
    ],
)
def test_link_layers(linktype: int, frame: bytes) -> None:
    segment = FrameDecoder().decode(frame, 0, len(frame), linktype, len(frame))
    assert segment is not None
    protocol, source, sport, destination, dport, payload, where, _, _, cut = segment
    assert (protocol, address_text(source), sport, address_text(destination), dport) == (
        UDP,
        "10.0.0.2",
        50000,
        "10.0.0.7",
        7340,
    )
    assert payload == b"hello"
    assert frame[where : where + 5] == b"hello"
    assert not cut


def test_an_unknown_link_type_is_named_with_those_the_reader_knows() -> None:
    """A capture of another link (802.11 radiotap, say) tells the user what it could read."""
    with pytest.raises(FrameError) as caught:
        FrameDecoder().decode(DATAGRAM, 0, len(DATAGRAM), 127, len(DATAGRAM))
    assert str(caught.value).startswith("link type 127 is none this reader knows: ")
    for number, name in LINK_TYPES.items():
        assert f"{number} ({name})" in str(caught.value)


def test_ethernet_padding_is_not_payload() -> None:
    frame = ethernet(DATAGRAM) + b"\0" * 20
    segment = FrameDecoder().decode(frame, 0, len(frame), LINKTYPE_ETHERNET, len(frame))
    assert segment is not None
    assert segment[5] == b"hello"


def test_ipv6_with_extension_headers() -> None:
    hop_by_hop = bytes([60, 0]) + b"\0" * 6  # next: destination options
    destination = bytes([17, 0]) + b"\0" * 6  # next: UDP
    packet = ipv6_udp(V6A, V6B, 5000, 7330, b"six", hop_by_hop + destination, first=0)
    for linktype, frame in (
        (LINKTYPE_IPV6, packet),
        (LINKTYPE_RAW, packet),
        (LINKTYPE_ETHERNET, ethernet(packet)),
        (LINKTYPE_NULL, null(packet)),
    ):
        segment = FrameDecoder().decode(frame, 0, len(frame), linktype, len(frame))
        assert segment is not None
        assert segment[5] == b"six"
        assert endpoint_text(segment[1], segment[2]) == ("[2001:db8::1]:5000")


def test_ipv4_fragments_are_put_together() -> None:
    body = struct.pack("!HHHH", 50000, 7340, 8 + 3000, 0) + bytes(range(256)) * 11 + b"x" * 184
    pieces = [body[:1480], body[1480:2960], body[2960:]]
    decoder = FrameDecoder()
    out = []
    # The last fragment first, then the others: order does not matter.
    for index in (2, 0, 1):
        offset = index * 1480 // 8
        more = 0x2000 if index < 2 else 0
        frame = ipv4("10.0.0.2", "10.0.0.7", 17, pieces[index], ident=9, fragment=more | offset)
        out.append(decoder.decode(frame, 0, len(frame), LINKTYPE_RAW, len(frame)))
    assert out[:2] == [None, None]
    whole = out[2]
    assert whole is not None
    assert whole[5] == body[8:]
    assert whole[6] == -1


def test_ipv6_fragments_are_put_together() -> None:
    payload = b"abcdefgh" * 300
    udp_bytes = struct.pack("!HHHH", 1, 2, 8 + len(payload), 0) + payload
    decoder = FrameDecoder()
    results = []
    for offset, last in ((0, False), (1200, True)):
        piece = udp_bytes[offset : offset + 1200] if not last else udp_bytes[offset:]
        header = struct.pack("!BBHI", 17, 0, offset | (0 if last else 1), 77)
        packet = struct.pack("!IHBB16s16s", 6 << 28, len(header) + len(piece), 44, 64, V6A, V6B)
        frame = packet + header + piece
        results.append(decoder.decode(frame, 0, len(frame), LINKTYPE_RAW, len(frame)))
    assert results[0] is None
    assert results[1] is not None
    assert results[1][5] == payload


def test_other_traffic_is_skipped_not_refused() -> None:
    decoder = FrameDecoder()
    arp = b"\xff" * 6 + b"\x04" * 6 + b"\x08\x06" + b"\0" * 28
    icmp = ipv4("10.0.0.2", "10.0.0.7", 1, b"\x08\0\0\0\0\0\0\0")
    assert decoder.decode(arp, 0, len(arp), LINKTYPE_ETHERNET, len(arp)) is None
    assert decoder.decode(icmp, 0, len(icmp), LINKTYPE_RAW, len(icmp)) is None
    assert decoder.skipped == 2


def test_a_frame_cut_by_the_snap_length_is_marked() -> None:
    frame = ipv4_tcp(A, B, 1, 0x18, b"CONNECT / RCTP/2.0\r\n")[:45]
    segment = FrameDecoder().decode(frame, 0, len(frame), LINKTYPE_RAW, len(frame) + 15)
    assert segment is not None
    assert segment[9] is True


@pytest.mark.parametrize(
    ("frame", "offset"),
    [
        (b"\x45" + b"\0" * 10, 0),  # IPv4 header cut short
        (bytes([0x43]) + DATAGRAM[1:], 0),  # header length 12
        (DATAGRAM[:20] + b"\0\0", 20),  # UDP header cut short
        (bytes([0x75]) + DATAGRAM[1:], 0),  # IP version 7
    ],
)
def test_broken_headers_are_located(frame: bytes, offset: int) -> None:
    with pytest.raises(FrameError) as caught:
        FrameDecoder().decode(b"PAD" + frame, 3, 3 + len(frame), LINKTYPE_RAW, len(frame))
    assert caught.value.offset == 3 + offset


@given(st.binary(max_size=200), st.sampled_from([0, 1, 101, 108, 113, 228, 229, 276, 999]))
def test_garbage_frames_raise_only_frame_error(frame: bytes, linktype: int) -> None:
    offsets = []
    try:
        FrameDecoder().decode(frame, 0, len(frame), linktype, len(frame))
    except FrameError as error:
        offsets.append(error.offset)
    assert all(0 <= offset <= len(frame) for offset in offsets)
