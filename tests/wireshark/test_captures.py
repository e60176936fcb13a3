"""tshark with the generated plugin on every recorded capture of captures/.

- no Lua error, nothing on tshark's standard error (a plugin that fails to load still exits 0);
- no malformed packet and no expert error in the good captures, and exactly the malformed parts
  listed in malformed.expected.json in that one;
- the analysis of each capture as the plugin shows it is its NAME.expected.json's `tshark` part;
- every message the plugin shows is what rcmlconf's codecs decode from the same bytes: each
  data-stream datagram (UDP 7330), each RSP packet (UDP 7340, with CUBO's model), each RCTP
  control message (TCP 7330, the connection's bytes read by `MessageReader`).
"""

from __future__ import annotations

from pathlib import Path

import pytest
from support.rsp_models import robot_model
from support.wireshark_checks import check_datastream, check_rctp_stream, check_rsp
from support.wireshark_pcaps import (
    CAPTURES,
    PLUGINS,
    load_json,
    need_tshark,
    plugin,
    run,
    segments,
    tcp_streams,
)

from rcmlconf.wireshark.tshark import Run, analyse

PCAPS = sorted(CAPTURES.glob("*.pcap"))
#: Each capture's description and expected analysis.
NAMES = [pcap.stem for pcap in PCAPS]
MALFORMED = "malformed"
RCTP_PORT, RSP_PORT = 7330, 7340


@pytest.fixture(scope="module")
def lua(tmp_path_factory: pytest.TempPathFactory) -> Path:
    need_tshark()
    return plugin(tmp_path_factory.mktemp("lua"), "CUBO")


def _run(name: str, lua: Path) -> Run:
    return run(CAPTURES / f"{name}.pcap", lua)


def test_the_captures_are_there() -> None:
    assert set(NAMES) == {"rctp-session", "rctp-impaired", "rsp-cubo-impaired", MALFORMED}
    readme = (CAPTURES / "README.md").read_text(encoding="utf-8")
    for name in NAMES:
        assert f"{name}.pcap" in readme
        assert (CAPTURES / f"{name}.expected.json").exists()
        assert (CAPTURES / f"{name}.pcap").stat().st_size < 300_000  # small enough to read


@pytest.mark.parametrize("name", NAMES)
def test_no_lua_error(name: str, lua: Path) -> None:
    result = _run(name, lua)
    assert result.problems == []
    assert [f.number for f in result.frames if f.lua_errors] == []
    # Every datagram and segment with bytes on our ports is one of ours.
    for frame in result.frames:
        ports = (
            {frame.source[1], frame.destination[1]} if frame.source and frame.destination else set()
        )
        if ports & {RCTP_PORT, RSP_PORT} and frame.transport == "udp":
            assert frame.layers, frame.number


@pytest.mark.parametrize("name", NAMES)
def test_malformed_only_where_expected(name: str, lua: Path) -> None:
    result = _run(name, lua)
    errors = [f.number for f in result.frames if f.errors or f.malformed]
    if name != MALFORMED:
        assert errors == []
        return
    expected = load_json(CAPTURES / f"{name}.expected.json")["tshark"]
    assert isinstance(expected, dict)
    listed = expected["malformed"]
    assert isinstance(listed, list)
    assert errors == [entry["frame"] for entry in listed]
    # RCTP control, the data stream and RSP: each has its malformed parts there.
    assert {entry["protocol"] for entry in listed} == {"rctp", "rctpds", "rcmlrsp"}


@pytest.mark.parametrize("name", NAMES)
def test_expected_analysis(name: str, lua: Path) -> None:
    expected = load_json(CAPTURES / f"{name}.expected.json")
    assert expected["capture"] == f"{name}.pcap"
    assert expected["tshark"] == analyse(_run(name, lua))


def test_impaired_stream_matches_the_proxy(lua: Path) -> None:
    """What the capture shows of the client's impaired packets is what the proxy did to them."""
    expected = load_json(CAPTURES / "rctp-impaired.expected.json")
    proxy = expected["recorded"]["proxy"]["client_to_server"]  # type: ignore[index]
    flows = analyse(_run("rctp-impaired", lua))["rctpds"]["flows"]  # type: ignore[index]
    (client,) = [f for f in flows if f["destination"].endswith(f":{RCTP_PORT}")]
    assert client["packets"] == proxy["delivered"]
    assert client["expected"] == proxy["sent"]
    assert client["lost"] == proxy["lost"]
    assert client["duplicates"] == proxy["duplicated"]
    assert client["late"] > 0


def test_rsp_run_shows_retransmissions(lua: Path) -> None:
    tshark = analyse(_run("rsp-cubo-impaired", lua))["rcmlrsp"]
    motion = tshark["occurrences"]["DOWNLINK motion"]  # type: ignore[index]
    assert motion["repeats"] > 0  # memory commands sent again after their RTO
    robot = [f for f in tshark["flows"] if f["source"].endswith(f":{RSP_PORT}")]  # type: ignore[index]
    assert sum(f["lost"] for f in robot) > 0


@pytest.mark.parametrize("name", NAMES)
def test_datagrams_as_the_codecs_read_them(name: str, lua: Path) -> None:
    result = _run(name, lua)
    frames = {frame.number: frame for frame in result.frames}
    cubo = robot_model(PLUGINS["CUBO"])
    checked = 0
    for segment in segments(CAPTURES / f"{name}.pcap"):
        if segment.protocol != 17 or not segment.payload:
            continue
        ports = {segment.source[1], segment.destination[1]}
        frame = frames[segment.frame]
        if RCTP_PORT in ports:
            (layer,) = frame.of("rctpds")
            check_datastream(layer, segment.payload)
        elif RSP_PORT in ports:
            (layer,) = frame.of("rcmlrsp")
            check_rsp(layer, segment.payload, cubo)
        else:
            continue
        checked += 1
    assert checked == sum(1 for f in result.frames if f.transport == "udp" and f.layers)


@pytest.mark.parametrize("name", [n for n in NAMES if n != "rsp-cubo-impaired"])
def test_control_messages_as_the_codec_reads_them(name: str, lua: Path) -> None:
    result = _run(name, lua)
    checked = 0
    for direction in tcp_streams(CAPTURES / f"{name}.pcap"):
        frames = set(direction.frames)
        layers = [
            layer for frame in result.frames if frame.number in frames for layer in frame.of("rctp")
        ]
        checked += check_rctp_stream(layers, bytes(direction.data))
    expected = load_json(CAPTURES / f"{name}.expected.json")["tshark"]
    assert checked == expected["rctp"]["messages"]  # type: ignore[index]
