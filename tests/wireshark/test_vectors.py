"""tshark with the generated plugin on pcaps written from the shared vectors: every field it shows
is the core codec's decoding of the same bytes, and every malformed vector is marked malformed at
the codec's offset with the codec's rule (vectors/rctp, vectors/rsp, the RCTP transcripts).
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from support.rsp_models import robot_model
from support.wireshark_checks import check_datastream, check_rctp_stream, check_rsp, top_malformed
from support.wireshark_pcaps import (
    PLUGINS,
    VECTORS,
    load_json,
    need_tshark,
    plugin,
    run,
    tcp_streams,
    udp_pcap,
)

from rcmlconf.pcap.writer import Payload, write_pcap
from rcmlconf.rctp.datastream.packets import DataPayload, FlowPayload, UnknownPayload, pull_packet
from rcmlconf.rsp.codec import MapBody, RspCodec
from rcmlconf.wireshark.tshark import Run, run_fields

pytestmark = pytest.mark.usefixtures("tshark")

DATASTREAM = load_json(VECTORS / "rctp" / "packets.json")
RSP = load_json(VECTORS / "rsp" / "packets.json")
TRANSCRIPTS = sorted((VECTORS / "rctp" / "transcripts").glob("*.json"))
OTHER = {"client": "server", "server": "client"}


@pytest.fixture(scope="module")
def tshark() -> None:
    need_tshark()


@pytest.fixture(scope="module")
def lua_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("lua")


def _clean(result: Run) -> None:
    assert result.problems == []
    assert [f.lua_errors for f in result.frames if f.lua_errors] == []


# -- the data stream -------------------------------------------------------------------------------


def _datastream_vectors() -> list[dict[str, object]]:
    vectors = []
    for group in ("valid", "malformed", "malformed_flow"):
        entries = DATASTREAM[group]
        assert isinstance(entries, list)
        vectors += [{**entry, "group": group} for entry in entries]
    return vectors


def test_datastream_vectors(lua_dir: Path, tmp_path: Path) -> None:
    # An empty datagram is never given to a dissector (UDP has nothing to hand on).
    vectors = [v for v in _datastream_vectors() if v["hex"]]
    datagrams = [bytes.fromhex(str(v["hex"])) for v in vectors]
    result = run(udp_pcap(tmp_path / "ds.pcap", datagrams, 7330), plugin(lua_dir, "none"))
    _clean(result)
    assert len(result.frames) == len(vectors)
    for frame, vector, data in zip(result.frames, vectors, datagrams, strict=True):
        (layer,) = frame.of("rctpds")
        check_datastream(layer, data)
        # A DATA body that is not its access's values needs the RCML to be seen: the plugin
        # shows DATA bodies as bytes (D-RCTP-20).
        malformed = vector["group"] != "valid" and "values" not in vector
        assert bool(frame.errors) == malformed, (vector["name"], frame.errors)
        if vector["group"] == "malformed" and "values" not in vector:
            assert top_malformed(layer) == (vector["offset"], vector["rule"]), vector["name"]


def test_datastream_on_any_port(lua_dir: Path, tmp_path: Path) -> None:
    """The heuristic finds the data stream on a port no one registered."""
    valid = DATASTREAM["valid"]
    assert isinstance(valid, list)
    datagrams = [bytes.fromhex(v["hex"]) for v in valid]
    result = run(udp_pcap(tmp_path / "any.pcap", datagrams, 50123), plugin(lua_dir, "none"))
    _clean(result)
    for frame, data in zip(result.frames, datagrams, strict=True):
        (layer,) = frame.of("rctpds")
        check_datastream(layer, data)


def test_datastream_fields(lua_dir: Path, tmp_path: Path) -> None:
    """`tshark -T fields -e ...`, as a user asks for them: the codec's numbers, packet by packet."""
    valid = DATASTREAM["valid"]
    assert isinstance(valid, list)
    datagrams = [bytes.fromhex(v["hex"]) for v in valid]
    pcap = udp_pcap(tmp_path / "fields.pcap", datagrams, 7330)
    names = ["rctpds.seq", "rctpds.tag", "rctpds.payload.type", "rctpds.flow.request_id"]
    rows = run_fields(pcap, plugin(lua_dir, "none"), names)
    assert len(rows) == len(datagrams)
    for (seq, tag, types, request_ids), data in zip(rows, datagrams, strict=True):
        packet = pull_packet(data)
        assert seq == [str(packet.sequence)]
        assert tag == [f"0x{packet.tag:08x}"]
        assert types == [str(_payload_type(p)) for p in packet.payloads]
        assert request_ids == [
            str(p.flow.request_id) for p in packet.payloads if isinstance(p, FlowPayload)
        ]


def _payload_type(payload: object) -> int:
    if isinstance(payload, UnknownPayload):
        return payload.type
    return 1 if isinstance(payload, DataPayload) else 2


# -- RSP ------------------------------------------------------------------------------------------


def _rsp_vectors(model: str) -> list[dict[str, object]]:
    out = []
    for group in ("valid", "malformed"):
        entries = RSP[group]
        assert isinstance(entries, list)
        out += [{**v, "group": group} for v in entries if v["model"] == model and v["hex"]]
    return out


@pytest.mark.parametrize("model", ["CUBO", "every-kind"])
def test_rsp_vectors_with_the_model(model: str, lua_dir: Path, tmp_path: Path) -> None:
    models = RSP["models"]
    assert isinstance(models, dict)
    robot = robot_model((VECTORS / models[model]).resolve())
    assert robot == robot_model(PLUGINS[model])  # the plugin's model is the vectors'
    vectors = _rsp_vectors(model)
    datagrams = [bytes.fromhex(str(v["hex"])) for v in vectors]
    result = run(udp_pcap(tmp_path / "rsp.pcap", datagrams, 7340), plugin(lua_dir, model))
    _clean(result)
    assert len(result.frames) == len(vectors)
    for frame, vector, data in zip(result.frames, vectors, datagrams, strict=True):
        (layer,) = frame.of("rcmlrsp")
        check_rsp(layer, data, robot)
        if vector["group"] == "malformed":
            assert top_malformed(layer) == (vector["offset"], vector["rule"]), vector["name"]
            assert frame.errors, vector["name"]
            assert frame.malformed, vector["name"]
        else:
            assert not frame.errors, (vector["name"], frame.errors)


def test_rsp_fields(lua_dir: Path, tmp_path: Path) -> None:
    """`tshark -T fields -e ...` on RSP: the codec's header and items, packet by packet."""
    vectors = [v for v in _rsp_vectors("CUBO") if v["group"] == "valid"]
    datagrams = [bytes.fromhex(str(v["hex"])) for v in vectors]
    pcap = udp_pcap(tmp_path / "fields.pcap", datagrams, 7340)
    names = ["rcmlrsp.type", "rcmlrsp.seq", "rcmlrsp.session_id", "rcmlrsp.device", "rcmlrsp.id"]
    rows = run_fields(pcap, plugin(lua_dir, "CUBO"), names)
    codec = RspCodec(robot_model(PLUGINS["CUBO"]))
    for (kind, seq, session, devices, ids), data in zip(rows, datagrams, strict=True):
        header, body = codec.pull_packet(data)
        assert kind == [str(int(header.type))]
        assert seq == [str(header.sequence)]
        assert int(session[0], 16) == header.session_id
        items = body.items if isinstance(body, MapBody) else ()
        assert devices == [codec.model.devices[item.device].name for item in items]
        assert ids == [str(item.id) for item in items if item.id is not None]


@pytest.mark.parametrize("model", ["CUBO", "every-kind"])
def test_rsp_vectors_without_a_model(model: str, lua_dir: Path, tmp_path: Path) -> None:
    """Without --model: the header and session bodies decoded, Device Maps and payloads bytes."""
    vectors = _rsp_vectors(model)
    datagrams = [bytes.fromhex(str(v["hex"])) for v in vectors]
    result = run(udp_pcap(tmp_path / "rsp.pcap", datagrams, 7340), plugin(lua_dir, "none"))
    _clean(result)
    for frame, data in zip(result.frames, datagrams, strict=True):
        (layer,) = frame.of("rcmlrsp")
        check_rsp(layer, data, None)


# -- RCTP control ----------------------------------------------------------------------------------


def _transcript_payloads(
    path: Path, number: int, piece: int | None, port: int = 7330
) -> list[Payload]:
    """A transcript's bytes on one TCP connection: each step's bytes cut in `piece`-byte
    segments (None: each step in one segment), the answer a step gets right after it."""
    steps = json.loads(path.read_text(encoding="utf-8"))["steps"]
    ends = {"client": ("127.0.0.1", 41000 + number), "server": ("127.0.0.1", port)}
    payloads: list[Payload] = []
    at = 1.0 + number

    def send(sender: str, data: bytes) -> None:
        nonlocal at
        size = piece or max(len(data), 1)
        for start in range(0, len(data), size):
            at += 0.0001
            payloads.append(
                Payload(at, "tcp", ends[sender], ends[OTHER[sender]], data[start : start + size])
            )

    for step in steps:
        if "raw" in step:
            receiver = step["raw"]
            sender = OTHER[receiver]
        else:
            sender = step.get("from") or step["timer"]
            receiver = OTHER[sender]
        send(sender, step["wire"].encode("latin-1"))
        if "reply" in step:
            send(receiver, step["reply"].encode("latin-1"))
    return payloads


def _pipelined(payloads: list[Payload]) -> list[Payload]:
    """Consecutive bytes of one direction in one segment: several messages to a segment."""
    merged: list[Payload] = []
    for payload in payloads:
        last = merged[-1] if merged else None
        if last is not None and (last.source, last.destination) == (
            payload.source,
            payload.destination,
        ):
            merged[-1] = Payload(
                last.at, "tcp", last.source, last.destination, last.data + payload.data
            )
        else:
            merged.append(payload)
    return merged


CUTS = ["whole", "7-byte segments", "1-byte segments", "pipelined", "on another port"]


@pytest.mark.parametrize("cut", CUTS)
def test_transcripts(cut: str, lua_dir: Path, tmp_path: Path) -> None:
    """Each transcript on a connection of its own; on another port than 7330 the heuristic finds
    RCTP by each connection's first line."""
    payloads: list[Payload] = []
    port = 7400 if cut == "on another port" else 7330
    for number, path in enumerate(TRANSCRIPTS):
        piece = {"7-byte segments": 7, "1-byte segments": 1}.get(cut)
        found = _transcript_payloads(path, number, piece, port)
        payloads += _pipelined(found) if cut == "pipelined" else found
    pcap = tmp_path / "transcripts.pcap"
    with pcap.open("wb") as file:
        write_pcap(file, payloads)
    result = run(pcap, plugin(lua_dir, "none"))
    _clean(result)
    checked = 0
    for direction in tcp_streams(pcap):
        layers = [
            layer
            for frame in result.frames
            if (frame.source, frame.destination) == (direction.source, direction.destination)
            for layer in frame.of("rctp")
        ]
        checked += check_rctp_stream(layers, bytes(direction.data))
    assert checked >= 60  # every message of every transcript
    # The transcripts that break framing, and only those, are malformed (the others are wrong
    # in ways that are well framed: expert warnings, not errors).
    broken = {
        frame.source[1] if frame.source and frame.source[1] != port else frame.destination[1]  # type: ignore[index]
        for frame in result.frames
        if frame.errors
    }
    framing = {
        41000 + number
        for number, path in enumerate(TRANSCRIPTS)
        if path.stem in ("errors-framing", "errors-oversize")
    }
    assert broken == framing


def test_a_capture_that_starts_in_the_middle(lua_dir: Path, tmp_path: Path) -> None:
    """The first segments of a connection not captured: what is left of the message they began
    is a continuation, not a malformed message, and the messages after it are read."""
    path = next(p for p in TRANSCRIPTS if p.stem == "normal-access")
    whole = tmp_path / "whole.pcap"
    with whole.open("wb") as file:
        write_pcap(file, _transcript_payloads(path, 0, 7))
    data = whole.read_bytes()
    records, position = [], 24
    while position < len(data):
        length = int.from_bytes(data[position + 8 : position + 12], "little")
        records.append(data[position : position + 16 + length])
        position += 16 + length
    cut = tmp_path / "cut.pcap"
    cut.write_bytes(data[:24] + b"".join(records[5:]))  # no handshake, no first two segments
    result = run(cut, plugin(lua_dir, "none"))
    _clean(result)
    assert [f.number for f in result.frames if f.errors] == []
    methods = [layer.first("rctp.method") for f in result.frames for layer in f.of("rctp")]
    # The first CONNECT was cut: the first request shown is the READ after it.
    assert next(m for m in methods if m is not None) == "READ"
    assert methods.count(None) >= 2  # what was left of CONNECT, and the responses
