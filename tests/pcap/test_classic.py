"""rcmlconf.pcap.classic: classic pcap in both byte orders and stamp resolutions; a broken
file is a CaptureError at its offset."""

from __future__ import annotations

import struct

import pytest
from support.pcaps import ipv4_udp, pcap

from rcmlconf.pcap.frames import LINKTYPE_RAW
from rcmlconf.pcap.reader import Capture
from rcmlconf.pcap.records import CaptureError

A, B = ("10.0.0.2", 50000), ("10.0.0.7", 7340)
DATAGRAM = ipv4_udp(A, B, b"hello")


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


def test_a_record_cut_short_is_located() -> None:
    data = pcap([(1.0, DATAGRAM)])
    with pytest.raises(CaptureError) as caught:
        list(Capture(data[:-3]).records())
    assert caught.value.offset == 24 + 8  # the record header's length field
    with pytest.raises(CaptureError) as caught:
        list(Capture(data + b"\0" * 5).records())
    assert caught.value.offset == len(data)


def test_pcap_of_another_version() -> None:
    data = bytearray(pcap([]))
    struct.pack_into("<H", data, 4, 3)
    with pytest.raises(CaptureError) as caught:
        list(Capture(bytes(data)).records())
    assert caught.value.offset == 4
