"""The dissector decodes every vector of vectors/rctp and vectors/rsp as the core's codecs do:
each datagram is put in a capture (after the SETUP that names its streams, for the data stream),
dissected, and its record's value and JSON field tree compared with the core's decoding and with
the vector; malformed vectors are reported at their offset with their rule."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
from support.pcaps import TcpFlow, dissect, ipv4_udp, pcap

from rcmlconf.dissect import RCTP_DATA, RSP, Options, Severity
from rcmlconf.dissect.output.fields_json import packet_json, rsp_json
from rcmlconf.dissect.output.record_json import JsonFormat, record_json
from rcmlconf.errors import ProtocolError
from rcmlconf.rctp.datastream.packets import MalformedFlowPayload, pull_packet
from rcmlconf.rsp.codec import RspCodec
from rcmlconf.rsp.codec.header import pull_header
from rcmlconf.validate.validator import load_robot, load_robot_model

VECTORS = Path(__file__).parents[2] / "vectors"
RCTP = json.loads((VECTORS / "rctp" / "packets.json").read_text(encoding="utf-8"))
RSP_VECTORS = json.loads((VECTORS / "rsp" / "packets.json").read_text(encoding="utf-8"))
TESTBOT = load_robot((VECTORS / RCTP["rcml"]).resolve())
MODELS = {
    key: load_robot_model((VECTORS / path).resolve()) for key, path in RSP_VECTORS["models"].items()
}
CLIENT, SERVER = ("10.0.0.2", 40000), ("10.0.0.7", 7330)
DATA_CLIENT, DATA_SERVER = ("10.0.0.2", 46000), ("10.0.0.7", 7330)
LOCAL, ROBOT = ("10.0.0.2", 50000), ("10.0.0.7", 7340)


def data_capture(data: bytes, streams: dict[int, str], direction: str) -> bytes:
    """A session that sets up `streams` (id -> access path) with the datagram's tag, then the
    datagram, robot to client (`read`) or client to robot (`write`)."""
    tag = data[4:8].hex() if len(data) >= 8 else "00000000"
    flow = TcpFlow(CLIENT, SERVER).handshake()
    flow.send(CLIENT, b"CONNECT /testbot RCTP/2.0\r\nCSeq: 1\r\n\r\n")
    flow.send(SERVER, b"RCTP/2.0 200 OK\r\nCSeq: 1\r\nSession: abcdefgh1234;timeout=60\r\n\r\n")
    for cseq, (stream, path) in enumerate(sorted(streams.items()), 2):
        flow.send(
            CLIENT,
            f"SETUP {path} RCTP/2.0\r\nCSeq: {cseq}\r\nSession: abcdefgh1234\r\n"
            f"Transport: udp;client_port={DATA_CLIENT[1]};mode=both\r\n\r\n".encode(),
        )
        flow.send(
            SERVER,
            f"RCTP/2.0 200 OK\r\nCSeq: {cseq}\r\nSession: abcdefgh1234\r\nTransport: udp;"
            f"client_port={DATA_CLIENT[1]};server_port={DATA_SERVER[1]};tag={tag};mode=both;"
            f"stream={stream}\r\n\r\n".encode(),
        )
    source, destination = (
        (DATA_SERVER, DATA_CLIENT) if direction == "read" else (DATA_CLIENT, DATA_SERVER)
    )
    return pcap([*flow.frames, (flow.time + 0.01, ipv4_udp(source, destination, data))])


def streams_of(case: dict[str, Any]) -> tuple[dict[int, str], str]:
    streams, direction = {}, "write"
    for payload in case.get("packet", {}).get("payloads", []):
        if "values" in payload:
            streams[payload["stream"]] = payload["values"]["access"]
            direction = payload["values"]["direction"]
    if "values" in case and "payload" in case["values"]:
        data = bytes.fromhex(case["hex"])
        stream = pull_packet(data).payloads[case["values"]["payload"]].stream
        streams[stream] = case["values"]["access"]
        direction = case["values"]["direction"]
    return streams, direction


def the_datagram(dissected: Any) -> Any:
    (record,) = [r for r in dissected.records if r.protocol == RCTP_DATA]
    return record


def same_json(record: Any, model: Any = None) -> None:
    """The hand-written JSON line is json's, value for value."""
    assert json.loads(JsonFormat(model).line(record)) == json.loads(
        json.dumps(record_json(record, model))
    )


@pytest.mark.parametrize("case", RCTP["valid"], ids=lambda c: c["name"])
def test_data_stream_vector(case: dict[str, Any]) -> None:
    data = bytes.fromhex(case["hex"])
    streams, direction = streams_of(case)
    dissected = dissect(data_capture(data, streams, direction), Options(rcml=TESTBOT))
    record = the_datagram(dissected)
    assert record.malformed is None
    assert record.value == pull_packet(data)  # the core's decoding, object for object
    assert record.sequence == case["packet"]["sequence"]
    assert packet_json(record.value, record.extra) == case["packet"]
    same_json(record)
    assert not [f for f in dissected.analysis.findings if f.severity is Severity.ERROR]


@pytest.mark.parametrize("case", RCTP["valid"], ids=lambda c: c["name"])
def test_data_stream_vector_without_the_rcml(case: dict[str, Any]) -> None:
    data = bytes.fromhex(case["hex"])
    dissected = dissect(pcap([(1.0, ipv4_udp(DATA_CLIENT, DATA_SERVER, data))]))
    record = the_datagram(dissected)
    expected = {
        **case["packet"],
        "payloads": [
            {k: v for k, v in p.items() if k != "values"} for p in case["packet"]["payloads"]
        ],
    }
    assert packet_json(record.value) == expected


@pytest.mark.parametrize("case", RCTP["malformed"], ids=lambda c: c["name"])
def test_malformed_data_stream_vector(case: dict[str, Any]) -> None:
    data = bytes.fromhex(case["hex"])
    streams, direction = streams_of(case)
    dissected = dissect(data_capture(data, streams, direction), Options(rcml=TESTBOT))
    record = the_datagram(dissected)
    if "values" in case:
        # The layout holds; the DATA body is not the access's values (R-RCTP-40).
        assert record.malformed is None
        (finding,) = [f for f in dissected.analysis.findings if f.rule == case["rule"]]
        assert f"(byte {case['offset']})" in finding.text
        assert finding.severity is Severity.ERROR
        return
    with pytest.raises(ProtocolError) as core:
        pull_packet(data)
    malformed = record.malformed
    assert malformed is not None
    assert (malformed.offset, malformed.reason) == (core.value.offset, core.value.reason)
    assert malformed.offset == case["offset"]
    assert malformed.rule == (case["rule"] or "R-RCTP-39")
    # The capture's own byte: the datagram ends the file.
    size = len(data_capture(data, streams, direction))
    assert malformed.file_offset == size - len(data) + case["offset"]
    same_json(record)


@pytest.mark.parametrize("case", RCTP["malformed_flow"], ids=lambda c: c["name"])
def test_malformed_flow_vector(case: dict[str, Any]) -> None:
    data = bytes.fromhex(case["hex"])
    dissected = dissect(pcap([(1.0, ipv4_udp(DATA_CLIENT, DATA_SERVER, data))]))
    record = the_datagram(dissected)
    assert record.malformed is None
    assert record.value == pull_packet(data)
    payload = record.value.payloads[case["payload"]]
    assert isinstance(payload, MalformedFlowPayload)
    assert payload.offset == case["offset"]
    findings = [f for f in dissected.analysis.findings if f.rule == "R-RCTP-52"]
    assert findings
    assert f"(byte {case['offset']})" in findings[0].text
    assert findings[0].file_offset == 24 + 16 + 28 + case["offset"]
    assert ("owed a NACK 5" in findings[0].text) == (case["answer"] == "malformed")


# -- RSP -------------------------------------------------------------------------------------------


def rsp_capture(data: bytes) -> bytes:
    return pcap([(1.0, ipv4_udp(LOCAL, ROBOT, data))])


def the_packet(dissected: Any) -> Any:
    (record,) = [r for r in dissected.records if r.protocol == RSP]
    return record


@pytest.mark.parametrize("case", RSP_VECTORS["valid"], ids=lambda c: c["name"])
def test_rsp_vector(case: dict[str, Any]) -> None:
    data = bytes.fromhex(case["hex"])
    model = MODELS[case["model"]]
    record = the_packet(dissect(rsp_capture(data), Options(rsp_model=model)))
    assert record.malformed is None
    core = RspCodec(model).pull_packet(data)
    assert record.value.header == core.header
    # NaN is not NaN: the bodies are compared in their JSON form, where it is "NaN".
    assert rsp_json(record.value, model) == rsp_json(core, model) == case["packet"]
    assert record.kind == case["packet"]["header"]["type"]
    same_json(record, model)


@pytest.mark.parametrize("case", RSP_VECTORS["valid"], ids=lambda c: c["name"])
def test_rsp_vector_without_a_model(case: dict[str, Any]) -> None:
    data = bytes.fromhex(case["hex"])
    record = the_packet(dissect(rsp_capture(data)))
    assert record.malformed is None
    shown = rsp_json(record.value, None)
    assert shown["header"] == case["packet"]["header"]
    assert record.value.header == pull_header(data)
    if "items" in case["packet"]["body"]:
        assert shown["body"] == {"bytes": data[20:].hex()}  # a map body needs the model
    else:
        assert shown["body"] == case["packet"]["body"]  # session bodies need none
    same_json(record)


@pytest.mark.parametrize("case", RSP_VECTORS["malformed"], ids=lambda c: c["name"])
def test_malformed_rsp_vector(case: dict[str, Any]) -> None:
    data = bytes.fromhex(case["hex"])
    model = MODELS[case["model"]]
    dissected = dissect(rsp_capture(data), Options(rsp_model=model, decode_as=(("rsp", 7340),)))
    record = the_packet(dissected)
    with pytest.raises(ProtocolError) as core:
        RspCodec(model).pull_packet(data)
    malformed = record.malformed
    assert malformed is not None
    assert (malformed.offset, malformed.rule) == (case["offset"], case["rule"])
    assert (malformed.offset, malformed.reason) == (core.value.offset, core.value.reason)
    assert malformed.file_offset == 24 + 16 + 28 + case["offset"]
    assert any(f.rule == case["rule"] for f in dissected.analysis.findings)
    same_json(record, model)
