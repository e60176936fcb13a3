"""rcmlconf.pcap.reader: pcap and pcapng, link layers, IPv4 and IPv6, TCP and UDP; broken files
are a CaptureError at their offset, and nothing else escapes."""

from __future__ import annotations

import contextlib
import io
import os
import struct
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st
from support.pcaps import (
    epb,
    ethernet,
    idb,
    ipv4,
    ipv4_tcp,
    ipv4_udp,
    ipv6_udp,
    nrb,
    null,
    opb,
    pcap,
    shb,
    sll,
    sll2,
    spb,
)

from rcmlconf.pcap.reader import (
    LINKTYPE_ETHERNET,
    LINKTYPE_IPV6,
    LINKTYPE_LINUX_SLL,
    LINKTYPE_LINUX_SLL2,
    LINKTYPE_LOOP,
    LINKTYPE_NULL,
    LINKTYPE_RAW,
    TCP,
    UDP,
    Capture,
    CaptureError,
    FrameDecoder,
    FrameError,
    address_text,
    endpoint_text,
)
from rcmlconf.pcap.writer import Payload, write_pcap

A, B = ("10.0.0.2", 50000), ("10.0.0.7", 7340)
DATAGRAM = ipv4_udp(A, B, b"hello")
V6A = bytes.fromhex("20010db8000000000000000000000001")
V6B = bytes.fromhex("20010db8000000000000000000000002")


def frames(data: bytes) -> list[tuple[float, int, bytes]]:
    return list(Capture(data).frames())


# -- pcap --------------------------------------------------------------------------------------


@pytest.mark.parametrize("order", ["<", ">"])
@pytest.mark.parametrize("nanoseconds", [False, True])
def test_pcap_both_byte_orders_and_resolutions(order: str, nanoseconds: bool) -> None:
    data = pcap([(1.5, DATAGRAM), (2.000123, DATAGRAM)], order=order, nanoseconds=nanoseconds)
    capture = Capture(data)
    assert capture.format == "pcap"
    assert capture.decimals == (9 if nanoseconds else 6)
    got = list(capture.frames())
    assert [(t, link, f) for t, link, f in got] == [
        (pytest.approx(1.5), LINKTYPE_RAW, DATAGRAM),
        (pytest.approx(2.000123, abs=1e-9), LINKTYPE_RAW, DATAGRAM),
    ]


def test_our_writer_reads_back() -> None:
    file = io.BytesIO()
    write_pcap(file, [Payload(10.25, "udp", A, B, b"x" * 30), Payload(11.0, "tcp", A, B, b"y")])
    decoder = FrameDecoder()
    capture = Capture(file.getvalue())
    segments = [
        decoder.decode(capture.data, s, e, link, n) for _, link, s, e, n in capture.records()
    ]
    assert segments[0] is not None
    assert segments[0][0] == UDP
    assert segments[0][5] == b"x" * 30
    # a handshake (SYN, SYN-ACK, ACK), then the byte
    assert [s[8] & 0x12 for s in segments[1:4] if s is not None] == [0x02, 0x12, 0x10]
    last = segments[4]
    assert last is not None
    assert last[0] == TCP
    assert last[5] == b"y"


def test_a_record_cut_short_is_located() -> None:
    data = pcap([(1.0, DATAGRAM)])
    with pytest.raises(CaptureError) as caught:
        list(Capture(data[:-3]).records())
    assert caught.value.offset == 24 + 8  # the record header's length field
    with pytest.raises(CaptureError) as caught:
        list(Capture(data + b"\0" * 5).records())
    assert caught.value.offset == len(data)


@pytest.mark.parametrize(
    "data",
    [b"", b"\xd4\xc3", b"GIF89a...", b"\xd4\xc3\xb2\xa1" + b"\0" * 8, b"\0" * 64],
)
def test_not_a_capture(data: bytes) -> None:
    with pytest.raises(CaptureError):
        Capture(data)


def test_pcap_of_another_version() -> None:
    data = bytearray(pcap([]))
    struct.pack_into("<H", data, 4, 3)
    with pytest.raises(CaptureError) as caught:
        list(Capture(bytes(data)).records())
    assert caught.value.offset == 4


def test_open_maps_the_file(tmp_path) -> None:  # type: ignore[no-untyped-def]
    path = tmp_path / "one.pcap"
    path.write_bytes(pcap([(1.0, DATAGRAM)]))
    with Capture.open(path) as capture:
        assert [f for _, _, f in capture.frames()] == [DATAGRAM]
        assert capture.first_time() == pytest.approx(1.0)
    empty = tmp_path / "empty.pcap"
    empty.write_bytes(b"")
    with pytest.raises(CaptureError):
        Capture.open(empty)


@pytest.mark.skipif(not Path("/proc/self/fd").exists(), reason="needs Linux /proc")
def test_a_pipe_is_read_as_it_comes() -> None:
    """A pipe (/dev/stdin, <(tcpdump -w -)) has no size to map: it is read, not taken for an
    empty file."""
    data = pcap([(1.0, DATAGRAM)])
    read, write = os.pipe()
    try:
        os.write(write, data)  # less than a pipe holds
        os.close(write)
        with Capture.open(f"/proc/self/fd/{read}") as capture:
            assert [f for _, _, f in capture.frames()] == [DATAGRAM]
    finally:
        os.close(read)


@pytest.mark.skipif(not Path("/dev/zero").exists(), reason="needs /dev/zero")
def test_an_endless_device_is_refused_by_its_first_bytes() -> None:
    with pytest.raises(CaptureError, match=r"not a pcap or pcapng file \(it starts with 00000000"):
        Capture.open("/dev/zero")


def test_a_stream_is_read_up_to_a_limit() -> None:
    data = pcap([(1.0, DATAGRAM)] * 40)
    assert len(list(Capture.read(io.BytesIO(data), "pipe", limit=len(data)).frames())) == 40
    with pytest.raises(CaptureError, match=f"more than {len(data) - 1:,} bytes from a pipe"):
        Capture.read(io.BytesIO(data), "pipe", limit=len(data) - 1)


# -- pcapng ------------------------------------------------------------------------------------


@pytest.mark.parametrize("order", ["<", ">"])
def test_pcapng_blocks_interfaces_and_resolutions(order: str) -> None:
    data = b"".join(
        [
            shb(order),
            idb(LINKTYPE_RAW, order),  # microseconds by default
            idb(LINKTYPE_ETHERNET, order, tsresol=9, tsoffset=100),  # nanoseconds, +100 s
            idb(LINKTYPE_RAW, order, tsresol=0x80 | 10),  # 2^-10 s
            nrb(order),
            epb(0, 1_500_000, DATAGRAM, order),
            epb(1, 2_000_000_001, ethernet(DATAGRAM), order),
            epb(2, 3 * 1024 + 512, DATAGRAM, order),
            spb(DATAGRAM, order),
            opb(0, 4_000_000, DATAGRAM, order),
        ]
    )
    capture = Capture(data)
    assert capture.format == "pcapng"
    assert capture.decimals == 9
    got = list(capture.frames())
    assert [link for _, link, _ in got] == [101, 1, 101, 101, 101]
    times = [t for t, _, _ in got]
    assert times == pytest.approx([1.5, 102.000000001, 3.5, 3.5, 4.0], abs=1e-9)
    assert got[1][2] == ethernet(DATAGRAM)
    assert all(f == DATAGRAM for i, (_, _, f) in enumerate(got) if i != 1)


def test_pcapng_sections_in_both_orders() -> None:
    data = shb("<") + idb(LINKTYPE_RAW, "<") + epb(0, 1, DATAGRAM, "<")
    data += shb(">") + idb(LINKTYPE_ETHERNET, ">") + epb(0, 2, ethernet(DATAGRAM), ">")
    assert [link for _, link, _ in frames(data)] == [LINKTYPE_RAW, LINKTYPE_ETHERNET]


def test_pcapng_errors_are_located() -> None:
    good = shb() + idb(LINKTYPE_RAW) + epb(0, 1, DATAGRAM)
    with pytest.raises(CaptureError) as caught:
        list(Capture(good[:-4]).records())  # the last block's trailing length is missing
    assert caught.value.offset == len(shb() + idb(LINKTYPE_RAW)) + 4
    no_interface = shb() + epb(0, 1, DATAGRAM)
    with pytest.raises(CaptureError, match="interface 0"):
        list(Capture(no_interface).records())
    bad_magic = bytearray(good)
    bad_magic[8:12] = b"\0\0\0\0"
    with pytest.raises(CaptureError) as caught:
        list(Capture(bytes(bad_magic)).records())
    assert caught.value.offset == 8
    odd = bytearray(good)
    struct.pack_into("<I", odd, len(shb()) + 4, 21)
    with pytest.raises(CaptureError, match="multiple of 4"):
        list(Capture(bytes(odd)).records())


# -- link layers and IP ----------------------------------------------------------------------


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


@given(st.binary(max_size=300))
def test_garbage_files_raise_only_capture_error(data: bytes) -> None:
    for prefix in (b"", pcap([])[:24], shb() + idb(LINKTYPE_ETHERNET)):
        offsets = []
        try:
            capture = Capture(prefix + data)
            decoder = FrameDecoder()
            for _, linktype, start, end, length in capture.records():
                with contextlib.suppress(FrameError):
                    decoder.decode(capture.data, start, end, linktype, length)
        except CaptureError as error:
            offsets.append(error.offset)
        assert all(0 <= offset <= len(prefix + data) for offset in offsets)


@given(st.binary(max_size=200), st.sampled_from([0, 1, 101, 108, 113, 228, 229, 276, 999]))
def test_garbage_frames_raise_only_frame_error(frame: bytes, linktype: int) -> None:
    offsets = []
    try:
        FrameDecoder().decode(frame, 0, len(frame), linktype, len(frame))
    except FrameError as error:
        offsets.append(error.offset)
    assert all(0 <= offset <= len(frame) for offset in offsets)
