"""Whatever a capture holds, the dissector lets nothing escape: a file that is no capture is a
CaptureError; inside one, broken files, frames and messages become the analysis's problems and
findings, never exceptions."""

from __future__ import annotations

import contextlib

from hypothesis import given
from hypothesis import strategies as st
from support.pcaps import TcpFlow, dissect, epb, idb, ipv4_udp, pcap, shb

from rcmlconf.dissect import Dissector, Options
from rcmlconf.dissect.output.analysis_json import analysis_json
from rcmlconf.dissect.output.analysis_text import analysis_lines
from rcmlconf.dissect.output.record_json import JsonFormat
from rcmlconf.dissect.output.record_text import TextFormat
from rcmlconf.pcap.reader import Capture
from rcmlconf.pcap.records import CaptureError
from rcmlconf.scapy_layers import capture as layers

PORTS = st.sampled_from([7330, 7340, 9999])


def everything(data: bytes, options: Options | None = None) -> None:
    """Dissect, and write every record and the analysis in both forms."""
    try:
        capture = Capture(data)
    except CaptureError:
        return
    text, json = TextFormat(), JsonFormat()
    records = []
    analysis = Dissector(options or Options(), records.append).run(capture)
    for record in records:
        text.line(record)
        json.line(record)
    list(analysis_lines(analysis))
    analysis_json(analysis)


@given(st.binary(max_size=400))
def test_garbage_after_a_pcap_header(data: bytes) -> None:
    everything(pcap([])[:24] + data)


@given(st.lists(st.tuples(PORTS, PORTS, st.binary(max_size=60)), max_size=12))
def test_garbage_datagrams(datagrams: list[tuple[int, int, bytes]]) -> None:
    frames = [
        (1.0 + i, ipv4_udp(("10.0.0.2", sport), ("10.0.0.7", dport), payload))
        for i, (sport, dport, payload) in enumerate(datagrams)
    ]
    data = pcap(frames)
    everything(data)
    everything(data, Options(heuristics=False, decode_as=(("rsp", 9999),)))


@given(st.lists(st.tuples(st.booleans(), st.binary(max_size=40)), max_size=12))
def test_garbage_control_connections(segments: list[tuple[bool, bytes]]) -> None:
    flow = TcpFlow(("10.0.0.2", 40000), ("10.0.0.7", 7330)).handshake()
    for from_client, data in segments:
        flow.send(flow.client if from_client else flow.server, data)
    everything(pcap(flow.frames))


@given(
    st.lists(
        st.sampled_from(
            [
                b"CONNECT /rover RCTP/2.0\r\nCSeq: 1\r\n\r\n",
                b"RCTP/2.0 200 OK\r\nCSeq: 1\r\nSession: abcdefgh1234;timeout=60\r\n\r\n",
                b"SETUP /a RCTP/2.0\r\nCSeq: 2\r\nSession: abcdefgh1234\r\n"
                b"Transport: udp;client_port=9\r\n\r\n",
                b"RCTP/2.0 200 OK\r\nCSeq: 2\r\nTransport: udp;server_port=7;tag=00000001;"
                b"stream=1\r\n\r\n",
                b"BYE * RCTP/2.0\r\nCSeq: 3\r\n\r\n",
                b"GO /a RCTP/2.0\r\nCSeq: 9\r\nSession: zz\r\n\r\n",
                b"RCTP/2.0 455 Method Not Valid in This State\r\n\r\n",
                b"WRITE /a RCTP/2.0\r\nCSeq: 1\r\nContent-Length: 2\r\n\r\nab",
            ]
        ),
        max_size=10,
    ),
    st.lists(st.booleans(), min_size=10, max_size=10),
)
def test_any_order_of_messages(messages: list[bytes], sides: list[bool]) -> None:
    flow = TcpFlow(("10.0.0.2", 40000), ("10.0.0.7", 7330)).handshake()
    for message, from_client in zip(messages, sides, strict=False):
        flow.send(flow.client if from_client else flow.server, message)
    everything(pcap(flow.frames))
    result = dissect(pcap(flow.frames))
    assert len(result.records) == len(messages) or any(r.malformed for r in result.records)


def _one_of_each() -> list[tuple[float, bytes]]:
    """Frames of a control connection, an RSP HELLO and a data-stream packet."""
    flow = TcpFlow(("10.0.0.2", 40000), ("10.0.0.7", 7330)).handshake()
    flow.send(flow.client, b"CONNECT /rover RCTP/2.0\r\nCSeq: 1\r\n\r\n")
    flow.send(flow.server, b"RCTP/2.0 200 OK\r\nCSeq: 1\r\nSession: abcdefgh1234\r\n\r\n")
    hello = bytes.fromhex("0100010001000000000000000000000000000000") + bytes(18)
    data = bytes.fromhex("020100010badcafeebe6bf40800000000101000400000001")
    return [
        *flow.frames,
        (flow.time + 0.01, ipv4_udp(("10.0.0.2", 50000), ("10.0.0.7", 7340), hello)),
        (flow.time + 0.02, ipv4_udp(("10.0.0.7", 7330), ("10.0.0.2", 40000), data)),
    ]


def _pcapng(frames: list[tuple[float, bytes]]) -> bytes:
    return shb() + idb(101) + b"".join(epb(0, int(t * 1e6), f) for t, f in frames)


def test_a_capture_cut_at_every_length() -> None:
    """Each prefix of a pcap and of a pcapng file is no capture or a capture read up to its
    break, by the dissector and by the scapy layers (`dissect -V`, sniff) alike."""
    frames = _one_of_each()
    for whole in (pcap(frames), _pcapng(frames)):
        for length in range(len(whole)):
            everything(whole[:length])
            with contextlib.suppress(CaptureError):
                list(layers.messages(Capture(whole[:length])))
