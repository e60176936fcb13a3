"""rcmlconf.pcap.pcapng: its blocks, interfaces and stamp resolutions, sections in both byte
orders; a broken file is a CaptureError at its offset."""

from __future__ import annotations

import struct

import pytest
from support.pcaps import epb, ethernet, idb, ipv4_udp, nrb, opb, shb, spb

from rcmlconf.pcap.frames import LINKTYPE_ETHERNET, LINKTYPE_RAW
from rcmlconf.pcap.reader import Capture
from rcmlconf.pcap.records import CaptureError

A, B = ("10.0.0.2", 50000), ("10.0.0.7", 7340)
DATAGRAM = ipv4_udp(A, B, b"hello")


def frames(data: bytes) -> list[tuple[float, int, bytes]]:
    return list(Capture(data).frames())


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
