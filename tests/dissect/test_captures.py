"""Real captures of the reference implementation, dissected.

- The conformance harness's own captures: `rcmlconf run --capture DIR` against the embedded
  reference writes a pcap of each case (the reference server and robot on loopback); each must
  dissect without a trace of trouble in the dissector, and a few cases are checked in detail.
- captures/: recorded with dumpcap by captures/record.py; their NAME.expected.json says what
  tshark, with the generated plugin, counts in them and what the recorder knows. The dissector's
  analysis must count the same.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
from support.pcaps import Dissected, dissect

from rcmlconf.dissect import RCTP, RCTP_DATA, RSP, Options, Severity
from rcmlconf.validate.validator import load_robot_model

ROOT = Path(__file__).parents[2]
CAPTURES = ROOT / "captures"
CUBO = load_robot_model(ROOT / "rcmlconf" / "reference" / "robots" / "cubo" / "cubo.rmodel")
ONLY = (
    "rctp/stream/*",
    "rctp/state/*",
    "rctp/flow/*",
    "rctp/clock/*",
    "rsp/reliable/*",
    "rsp/header/*",
)


@pytest.fixture(scope="module")
def harness(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Each case's capture, by file name, from the harness run against the reference."""
    directory = tmp_path_factory.mktemp("captures")
    arguments = [sys.executable, "-m", "rcmlconf", "run", "--capture", str(directory)]
    for pattern in ONLY:
        arguments += ["--only", pattern]
    done = subprocess.run(arguments, capture_output=True, text=True, timeout=300, check=False)
    assert done.returncode == 0, done.stderr[-2000:]
    found = {path.name: path for path in directory.glob("*.pcap")}
    assert len(found) > 50
    return found


def dissect_file(path: Path, options: Options | None = None) -> Dissected:
    return dissect(path.read_bytes(), options)


def test_every_harness_capture_dissects(harness: dict[str, Path]) -> None:
    for name, path in sorted(harness.items()):
        model = CUBO if name.startswith("rsp_") else None
        dissected = dissect_file(path, Options(rsp_model=model))
        analysis = dissected.analysis
        assert analysis.capture.error is None, name
        assert not analysis.capture.problems, name
        assert dissected.records, name
        protocols = {r.protocol for r in dissected.records}
        assert protocols <= ({RSP} if name.startswith("rsp_") else {RCTP, RCTP_DATA}), name


def test_a_stream_that_pauses(harness: dict[str, Path]) -> None:
    dissected = dissect_file(harness["rctp_stream_pause.pcap"])
    assert [r.kind for r in dissected.records if r.protocol == RCTP][:5] == [
        "CONNECT",
        "200 OK",
        "SETUP",
        "200 OK",
        "GO",
    ]
    (control,) = dissected.analysis.control
    assert control.streams == {"/drive/wheels": "playing"}
    assert set(control.response_times) == {"CONNECT", "SETUP", "GO", "PAUSE"}
    (stream,) = dissected.analysis.streams
    assert stream.label == "stream 1 /drive/wheels (read)"
    assert stream.lost == 0
    assert not dissected.analysis.findings


@pytest.mark.parametrize(
    ("case", "rule", "offset"),
    [
        ("rctp_stream_drop-wrong-version.pcap", "R-RCTP-39", 0),
        ("rctp_stream_drop-broken-framing.pcap", "R-RCTP-39", None),
        ("rsp_header_other-version.pcap", "R-RSP-13", 0),
        ("rsp_header_unknown-type.pcap", "R-RSP-13", 4),
    ],
)
def test_cases_that_send_broken_packets(
    harness: dict[str, Path], case: str, rule: str, offset: int | None
) -> None:
    dissected = dissect_file(harness[case], Options(rsp_model=CUBO))
    broken = [r.malformed for r in dissected.records if r.malformed is not None]
    assert broken
    assert all(m.rule == rule for m in broken)
    if offset is not None:
        assert broken[0].offset == offset
    assert dissected.analysis.errors == len(broken)


def test_states_the_cases_break_on_purpose(harness: dict[str, Path]) -> None:
    """The state cases send methods in states that do not allow them, and the reference
    answers each as D-RCTP-13 and D-RCTP-14 say: warnings, and no error."""
    for name in (
        "rctp_state_idle-methods.pcap",
        "rctp_state_closing-methods.pcap",
        "rctp_state_stream-init.pcap",
        "rctp_state_stream-playing.pcap",
    ):
        analysis = dissect_file(harness[name]).analysis
        assert analysis.errors == 0, name
        refused = [status for c in analysis.control for _, status, _ in c.refused]
        assert refused, name
        assert set(refused) <= {454, 455}, name


# -- captures/ -------------------------------------------------------------------------------------


def expected(name: str) -> dict[str, Any]:
    path = CAPTURES / f"{name}.expected.json"
    if not path.exists() or not (CAPTURES / f"{name}.pcap").exists():
        pytest.skip(f"captures/{name} is not there")
    return json.loads(path.read_text(encoding="utf-8"))  # type: ignore[no-any-return]


def flows_match(dissected: Dissected, flows: list[dict[str, Any]], key: str) -> None:
    """Each flow tshark counts is a stream of ours with the same counts."""
    streams = {(s.source, s.destination, s.session): s for s in dissected.analysis.streams}
    for flow in flows:
        session = flow[key] if isinstance(flow[key], str) else f"{flow[key]:012x}"
        if session == "000000000000":
            continue  # HELLOs: the first packets of the session that follows (D-RSP-12)
        stream = streams[(flow["source"], flow["destination"], session)]
        assert (stream.lost, stream.duplicates, stream.late) == (
            flow["lost"],
            flow["duplicates"],
            flow["late"],
        ), flow
        assert stream.packets in (flow["packets"], flow["packets"] + 1)  # + the HELLO


def test_rctp_session_capture() -> None:
    tshark = expected("rctp-session")["tshark"]
    dissected = dissect_file(CAPTURES / "rctp-session.pcap")
    analysis = dissected.analysis
    assert analysis.capture.frames == tshark["frames"]
    assert analysis.capture.messages[RCTP] == tshark["rctp"]["messages"]
    assert analysis.capture.messages[RCTP_DATA] == tshark["rctpds"]["packets"]
    assert sorted(c.session or "" for c in analysis.control) == sorted(tshark["rctp"]["sessions"])
    assert sum(c.responses for c in analysis.control) == tshark["rctp"]["answered"]
    flows_match(dissected, tshark["rctpds"]["flows"], "tag")
    assert sum(h.answered for h in analysis.heartbeats) == len(tshark["rctpds"]["heartbeats"])
    assert analysis.errors == 0


def test_rctp_impaired_capture() -> None:
    tshark = expected("rctp-impaired")["tshark"]
    dissected = dissect_file(CAPTURES / "rctp-impaired.pcap")
    flows_match(dissected, tshark["rctpds"]["flows"], "tag")
    (beats,) = dissected.analysis.heartbeats
    assert beats.clock is not None
    best = min(tshark["rctpds"]["heartbeats"], key=lambda h: h["round_trip_us"])
    assert beats.clock.offset * 1e6 == pytest.approx(best["offset_us"], abs=1.5)
    assert beats.clock.delay * 1e6 == pytest.approx(best["round_trip_us"], abs=1.5)
    assert dissected.analysis.errors == 0


def test_rsp_cubo_impaired_capture() -> None:
    tshark = expected("rsp-cubo-impaired")["tshark"]["rcmlrsp"]
    dissected = dissect_file(CAPTURES / "rsp-cubo-impaired.pcap", Options(rsp_model=CUBO))
    assert dissected.analysis.capture.messages[RSP] == tshark["packets"]
    kinds: dict[str, int] = {}
    for record in dissected.records:
        kinds[record.kind] = kinds.get(record.kind, 0) + 1
    assert kinds == tshark["types"]
    flows_match(dissected, tshark["flows"], "session_id")
    (session,) = dissected.analysis.rsp_sessions
    occurrences = tshark["occurrences"]
    sent = {k.split()[1]: v for k, v in occurrences.items() if not k.startswith("ACK")}
    assert session.occurrences == sum(v["ids"] for v in sent.values())
    assert session.resends == sent["motion"]["repeats"] + sent["lowBattery"]["repeats"]
    assert session.acknowledged == session.occurrences
    assert dissected.analysis.errors == 0


def test_malformed_capture() -> None:
    tshark = expected("malformed")["tshark"]
    dissected = dissect_file(CAPTURES / "malformed.pcap", Options(rsp_model=CUBO))
    found = {}
    for record in dissected.records:
        if record.malformed is not None:
            found[record.frame] = (record.malformed.reason, record.malformed.rule)
    flows = {f.frame: f for f in dissected.analysis.findings if f.rule == "R-RCTP-52"}
    for entry in tshark["malformed"]:
        if entry["rule"] == "R-RCTP-52":
            assert entry["frame"] in flows
            assert entry["reason"] in flows[entry["frame"]].text
            continue
        reason, rule = found[entry["frame"]]
        # The plugin words a value's fault its own way ("leftWheel/speed: ..."): ours is the
        # core codec's ("leftWheel: speed: ...").
        assert reason.replace(": ", "/", 1) == entry["reason"] or reason == entry["reason"]
        if entry["rule"] is not None:
            assert rule == entry["rule"]
    assert dissected.analysis.errors >= len(tshark["malformed"])
    assert all(f.severity is not Severity.ERROR or f.rule for f in dissected.analysis.findings)
