"""rcmlconf.pcap.reader: a capture mapped from a file or read from a pipe, our writer's files read
back; what is no capture, or breaks, is a CaptureError at its offset, and nothing else escapes."""

from __future__ import annotations

import contextlib
import io
import os
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st
from support.pcaps import idb, ipv4_udp, pcap, shb

from rcmlconf.pcap.frames import LINKTYPE_ETHERNET, TCP, UDP, FrameDecoder
from rcmlconf.pcap.reader import Capture
from rcmlconf.pcap.records import CaptureError, FrameError
from rcmlconf.pcap.writer import Payload, write_pcap

A, B = ("10.0.0.2", 50000), ("10.0.0.7", 7340)
DATAGRAM = ipv4_udp(A, B, b"hello")


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


@pytest.mark.parametrize(
    "data",
    [b"", b"\xd4\xc3", b"GIF89a...", b"\xd4\xc3\xb2\xa1" + b"\0" * 8, b"\0" * 64],
)
def test_not_a_capture(data: bytes) -> None:
    with pytest.raises(CaptureError):
        Capture(data)


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


def test_our_writer_writes_ipv6_with_good_checksums() -> None:
    """An IPv6 target's traffic (`run --target [::1]:P --capture`): IPv6 packets, each
    checksum right (scapy recomputes them), IPv4 ends mapped where the other end is IPv6."""
    from scapy.layers.inet import TCP as ScapyTCP
    from scapy.layers.inet import UDP as ScapyUDP
    from scapy.layers.inet6 import IPv6

    six, other = ("::1", 50000), ("::1", 7330)
    file = io.BytesIO()
    write_pcap(
        file, [Payload(1.0, "udp", six, other, b"x" * 31), Payload(2.0, "tcp", six, other, b"y")]
    )
    capture = Capture(file.getvalue())
    packets = [IPv6(capture.data[s:e]) for _, _, s, e, _ in capture.records()]
    assert [p.src for p in packets] == ["::1"] * 5
    for packet in packets:
        layer = packet[ScapyUDP] if ScapyUDP in packet else packet[ScapyTCP]
        given = layer.chksum
        del layer.chksum
        assert IPv6(bytes(packet))[type(layer)].chksum == given
    assert bytes(packets[0][ScapyUDP].payload) == b"x" * 31
    assert bytes(packets[-1][ScapyTCP].payload) == b"y"
