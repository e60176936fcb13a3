"""`rcmlconf dissect` as a user runs it: a process, real files, exit statuses, no traceback."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from support.pcaps import TcpFlow, ipv4_udp, pcap
from support.processes import run_without_stdin

ROOT = Path(__file__).parents[2]
CUBO = ROOT / "rcmlconf" / "reference" / "robots" / "cubo" / "cubo.rmodel"
ROVER = ROOT / "rcmlconf" / "reference" / "robots" / "rover" / "rover.rcml"
# The command as `rcmlconf` runs it.
MAIN = "from rcmlconf.cli import main; main()"
CLIENT, SERVER = ("10.0.0.2", 40000), ("10.0.0.7", 7330)
LOCAL, ROBOT = ("10.0.0.2", 50000), ("10.0.0.7", 7340)
# version 1, model 1, no encryption, HELLO, sequence 0, timestamp 0, session 0, last 0, buffer 0
HELLO = bytes.fromhex("0100010001000000000000000000000000000000")
HELLO += bytes(range(16)) + b"\0\x14"
DATA = bytes.fromhex("020100010badcafeebe6bf40800000000101000400000001")


def run(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    done = subprocess.run(
        [sys.executable, "-c", MAIN, "dissect", *args],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=cwd,
        check=False,
    )
    assert "Traceback" not in done.stderr, done.stderr
    return done


@pytest.fixture
def good(tmp_path: Path) -> Path:
    flow = TcpFlow(CLIENT, SERVER).handshake()
    flow.send(CLIENT, b"CONNECT /rover RCTP/2.0\r\nCSeq: 1\r\n\r\n")
    flow.send(SERVER, b"RCTP/2.0 200 OK\r\nCSeq: 1\r\nSession: abcdefgh1234;timeout=60\r\n\r\n")
    frames = [
        *flow.frames,
        (flow.time + 0.01, ipv4_udp(LOCAL, ROBOT, HELLO)),
        (flow.time + 0.02, ipv4_udp(SERVER, CLIENT, DATA)),
    ]
    path = tmp_path / "good.pcap"
    path.write_bytes(pcap(frames))
    return path


@pytest.fixture
def broken(tmp_path: Path) -> Path:
    path = tmp_path / "broken.pcap"
    path.write_bytes(pcap([(1.0, ipv4_udp(LOCAL, ROBOT, b"\x01\x00\x01"))]))
    return path


def test_a_clean_capture_exits_0(good: Path) -> None:
    done = run(str(good))
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    assert lines[0].startswith("1 0.00")
    assert "RCTP CONNECT /rover CSeq=1" in lines[0]
    assert "10.0.0.7:7330 → 10.0.0.2:40000 RCTP 200 OK CSeq=1 (CONNECT," in lines[1]
    assert "RSP HELLO seq=0" in lines[2]
    assert "RCTP-DATA DATA seq=1 tag=0badcafe s1:4B" in lines[3]
    assert "Analysis" in lines
    assert any(line.startswith("Findings: 0") for line in lines)
    assert "good.pcap" in done.stderr
    assert "0 errors" in done.stderr


def test_errors_found_exit_1(broken: Path) -> None:
    done = run(str(broken))
    assert done.returncode == 1
    assert "RSP malformed malformed: header of 3 bytes" in done.stdout
    assert "error: [R-RSP-13]" in done.stdout
    # One of each, said so.
    assert "Findings: 1 finding (1 error)" in done.stdout.splitlines()
    assert done.stderr == f"{broken}: 1 frame, 1 message, 1 error, 0 warnings\n"


def test_json_lines_then_the_analysis(good: Path) -> None:
    done = run("--format", "json", str(good))
    assert done.returncode == 0
    objects = [json.loads(line) for line in done.stdout.splitlines()]
    *messages, last = objects
    assert [m["type"] for m in messages] == ["CONNECT", "200 OK", "HELLO", "DATA"]
    assert messages[3]["fields"]["tag"] == "0badcafe"
    assert messages[2]["fields"]["body"]["period_ms"] == 20
    assert set(last) == {"version", "analysis"}
    assert last["version"] == 1
    assert last["analysis"]["errors"] == 0
    assert last["analysis"]["control"][0]["session"] == "abcdefgh1234"


def test_quiet_prints_the_analysis_only(good: Path) -> None:
    done = run("-q", str(good))
    assert done.stdout.lstrip().startswith("Analysis")


def test_models_decode_payloads(tmp_path: Path) -> None:
    from rcmlconf.rsp.codec import Encryption, Header, Item, MapBody, Packet, PacketType, RspCodec
    from rcmlconf.validate.validator import load_robot_model

    codec = RspCodec(load_robot_model(CUBO))
    header = Header(1, 1, Encryption.NONE, PacketType.DOWNLINK, 3, 60, 0xA1B2C3D4E5F6, 0, 0)
    downlink = codec.push_packet(Packet(header, MapBody((Item(0), Item(1, None, {"speed": -20})))))
    path = tmp_path / "cubo.pcap"
    path.write_bytes(pcap([(1.0, ipv4_udp(LOCAL, ROBOT, downlink))]))
    assert "body=6B" in run(str(path)).stdout  # a 4-byte map and a speed
    shown = run("--model", str(CUBO), "--model", str(ROVER), str(path)).stdout
    assert "base leftWheel{speed=-20}" in shown


def test_decode_as(tmp_path: Path) -> None:
    path = tmp_path / "other-port.pcap"
    path.write_bytes(pcap([(1.0, ipv4_udp(LOCAL, ("10.0.0.7", 9999), HELLO))]))
    assert "RSP HELLO" not in run("--no-heuristics", str(path)).stdout
    assert "RSP HELLO" in run("--no-heuristics", "--decode-as", "rsp=9999", str(path)).stdout
    assert "RSP HELLO" in run(str(path)).stdout  # recognised by its header


@pytest.mark.parametrize("value", ["rsp", "tcp=80", "rsp=0", "rsp=70000", "rctp=x"])
def test_bad_decode_as_is_a_usage_error(good: Path, value: str) -> None:
    done = run("--decode-as", value, str(good))
    assert done.returncode == 2
    assert "PROTO=PORT" in done.stderr


def test_unreadable_and_garbage_files_exit_2(tmp_path: Path) -> None:
    garbage = tmp_path / "garbage.pcap"
    garbage.write_bytes(b"this is not a capture at all")
    done = run(str(garbage))
    assert done.returncode == 2
    assert done.stderr.strip().splitlines() == [
        f"rcmlconf dissect: {garbage}: not a pcap or pcapng file (it starts with 74686973, no"
        " capture format's magic number) (byte 0)"
    ]
    missing = run(str(tmp_path / "missing.pcap"))
    assert missing.returncode == 2
    assert "cannot read" in missing.stderr
    assert run(str(tmp_path)).returncode == 2  # a directory


def test_a_file_cut_short_shows_what_it_holds_and_exits_2(good: Path, tmp_path: Path) -> None:
    cut = tmp_path / "cut.pcap"
    cut.write_bytes(good.read_bytes()[:-7])
    done = run(str(cut))
    assert done.returncode == 2
    assert "RCTP 200 OK" in done.stdout  # the records before the break
    assert "the file cannot be read past byte" in done.stdout
    assert "read up to there" in done.stderr


def test_an_invalid_model_exits_1(good: Path, tmp_path: Path) -> None:
    model = tmp_path / "bad.rmodel"
    model.write_text('<robotModel version="2" name="x" modelId="1"/>', encoding="utf-8")
    done = run("--model", str(model), str(good))
    assert done.returncode == 1
    assert "R-RSP-1" in done.stdout


def test_plot(good: Path, tmp_path: Path) -> None:
    pytest.importorskip("matplotlib")
    flow_frames = [
        (
            1.0 + i * 0.02 + (0.003 if i % 3 else 0),
            ipv4_udp(SERVER, CLIENT, DATA[:2] + i.to_bytes(2, "big") + DATA[4:]),
        )
        for i in range(50)
    ]
    capture = tmp_path / "stream.pcap"
    capture.write_bytes(pcap(flow_frames))
    image = tmp_path / "out.png"
    done = run("--plot", str(image), "-q", str(capture))
    assert done.returncode == 0, done.stderr
    assert image.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert f"{image}: 1 stream drawn" in done.stderr
    bad = run("--plot", str(tmp_path / "no" / "such" / "dir.png"), "-q", str(capture))
    assert bad.returncode == 2
    assert "--plot" in bad.stderr


@pytest.fixture
def stream(tmp_path: Path) -> Path:
    """A capture of one data stream of 50 packets."""
    capture = tmp_path / "stream.pcap"
    capture.write_bytes(
        pcap(
            [
                (
                    1.0 + i * 0.02,
                    ipv4_udp(SERVER, CLIENT, DATA[:2] + i.to_bytes(2, "big") + DATA[4:]),
                )
                for i in range(50)
            ]
        )
    )
    return capture


def test_plot_writes_the_path_as_given(stream: Path, tmp_path: Path) -> None:
    pytest.importorskip("matplotlib")
    image = tmp_path / "streams"  # no .png: written as it is named, as PNG all the same
    done = run("--plot", str(image), "-q", str(stream))
    assert done.returncode == 0, done.stderr
    assert image.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not image.with_name("streams.png").exists()
    assert f"{image}: 1 stream drawn" in done.stderr


def test_a_plot_path_that_cannot_be_written_is_refused_before_dissecting(
    stream: Path, tmp_path: Path
) -> None:
    # Below a regular file: no process can write there, root neither.
    unwritable = stream / "streams.png"
    done = run("--plot", str(unwritable), str(stream))
    assert done.returncode == 2
    assert done.stdout == ""  # not one message dissected
    assert done.stderr.splitlines()[-1] == (
        f"Error: Invalid value for '--plot': '{unwritable}' cannot be written: Not a directory"
    )


def test_an_existing_plot_file_is_left_as_it_is_when_dissecting_fails(tmp_path: Path) -> None:
    kept = tmp_path / "kept.png"
    kept.write_bytes(b"an earlier plot")
    garbage = tmp_path / "garbage.pcap"
    garbage.write_bytes(b"not a capture")
    assert run("--plot", str(kept), str(garbage)).returncode == 2
    assert kept.read_bytes() == b"an earlier plot"
    fresh = tmp_path / "fresh.png"
    assert run("--plot", str(fresh), str(garbage)).returncode == 2
    assert not fresh.exists()  # the writability test left nothing behind


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="needs /dev/full")
def test_plot_to_dev_full_is_one_line_and_makes_no_other_file(stream: Path) -> None:
    pytest.importorskip("matplotlib")
    beside = Path("/dev/full.png")
    before = beside.exists()
    done = run("--plot", "/dev/full", "-q", str(stream))
    assert done.returncode == 2
    assert "rcmlconf dissect: --plot /dev/full: cannot be written: No space left on device" in (
        done.stderr.splitlines()
    )
    assert beside.exists() == before


@pytest.mark.parametrize("option", [["--plot", "x.png"], ["--format", "json"]])
def test_verbose_takes_no_plot_or_json(good: Path, tmp_path: Path, option: list[str]) -> None:
    done = run("-V", *option, str(good), cwd=tmp_path)
    assert done.returncode == 2
    assert done.stdout == ""
    assert done.stderr.splitlines()[-1] == (
        "Error: -V prints each message's field tree as text, and no analysis: leave out --plot"
        " and --format json, or -V"
    )
    assert not (tmp_path / "x.png").exists()


def test_counts_of_one_are_singular(tmp_path: Path) -> None:
    one = tmp_path / "one.pcap"
    one.write_bytes(pcap([(1.0, ipv4_udp(LOCAL, ROBOT, HELLO))]))
    done = run("-q", str(one))
    assert done.returncode == 0, done.stderr
    assert done.stderr == f"{one}: 1 frame, 1 message, 0 errors, 0 warnings\n"


def test_verbose_prints_each_message_and_its_field_tree_from_the_scapy_layers(good: Path) -> None:
    done = run("-V", "--model", str(CUBO), str(good))
    assert done.returncode == 0, done.stderr
    assert "###[ RSP ]###" in done.stdout
    assert "client_nonce" in done.stdout
    bad = run("-V", str(ROVER))  # not a capture
    assert bad.returncode == 2
    assert "rcmlconf dissect" in bad.stderr
    assert "not a pcap or pcapng file" in bad.stderr
    # A capture that breaks is read up to there, as without -V.
    cut = good.with_name("cut.pcap")
    cut.write_bytes(good.read_bytes()[:-5])
    broken = run("-V", "--model", str(CUBO), str(cut))
    assert broken.returncode == 2
    assert "runs past the end of the file" in broken.stderr
    assert "read up to there" in broken.stderr
    assert broken.stdout.count("###[ RCTP Re") == done.stdout.count("###[ RCTP Re") == 2
    assert "###[ RSP ]###" in broken.stdout


def test_two_models_of_a_kind_are_refused(good: Path) -> None:
    """Only one robot model and one RCML can be used: a second of a kind is not silently
    dropped."""
    done = run("--model", str(CUBO), "--model", str(ROVER), "--model", str(CUBO), str(good))
    assert done.returncode == 2
    assert done.stdout == ""
    assert done.stderr.splitlines()[-1] == (
        f"Error: Invalid value for '--model': '{CUBO}' and '{CUBO}' are both a robot model: give"
        " one robot model and one RCML at most"
    )


@pytest.mark.parametrize("verbose", [[], ["-V"]])
def test_a_capture_of_one_byte_is_one_line(good: Path, tmp_path: Path, verbose: list[str]) -> None:
    cut = tmp_path / "cut.pcap"
    cut.write_bytes(good.read_bytes()[:1])
    done = run(*verbose, str(cut))
    assert done.returncode == 2
    assert done.stderr.splitlines() == [
        f"rcmlconf dissect: {cut}: 1 byte: too short for a pcap or pcapng file (byte 0)"
    ]


def test_standard_input_is_read_as_a_capture(good: Path) -> None:
    done = subprocess.run(
        [sys.executable, "-c", MAIN, "dissect", "-q", "-"],
        input=good.read_bytes(),
        capture_output=True,
        timeout=120,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    assert done.stderr.decode() == "-: 7 frames, 4 messages, 0 errors, 0 warnings\n"


@pytest.mark.parametrize(
    ("data", "reason"),
    [
        (
            bytes(range(256)) * 8,
            "not a pcap or pcapng file (it starts with 00010203, no capture format's magic number)",
        ),
        (b"\xd4\xc3", "2 bytes: too short for a pcap or pcapng file"),
    ],
    ids=["binary", "two bytes"],
)
def test_binary_standard_input_is_one_line(data: bytes, reason: str) -> None:
    done = subprocess.run(
        [sys.executable, "-c", MAIN, "dissect", "-"],
        input=data,
        capture_output=True,
        timeout=120,
        check=False,
    )
    assert done.returncode == 2
    assert done.stderr.decode().splitlines() == [f"rcmlconf dissect: -: {reason} (byte 0)"]


@pytest.mark.skipif(not Path("/dev/zero").exists(), reason="needs /dev/zero")
def test_an_endless_device_is_no_capture() -> None:
    done = run("/dev/zero")
    assert done.returncode == 2
    assert done.stderr.splitlines() == [
        "rcmlconf dissect: /dev/zero: not a pcap or pcapng file (it starts with 00000000, no"
        " capture format's magic number) (byte 0)"
    ]


def test_closed_standard_input_cannot_be_read() -> None:
    done = run_without_stdin(sys.executable, "-c", MAIN, "dissect", "-")
    assert done.returncode == 2
    assert done.stderr == "rcmlconf dissect: cannot read -: standard input is closed\n"


@pytest.mark.skipif(not Path("/proc/self/mem").exists(), reason="needs Linux /proc")
def test_an_unreadable_capture_is_one_line(tmp_path: Path) -> None:
    # Reading /proc/self/mem at offset 0 fails (EIO) for root too, where chmod 000 would not; the
    # name has a newline, shown escaped on the one line.
    unreadable = tmp_path / "new\nline.pcap"
    unreadable.symlink_to("/proc/self/mem")
    done = run(str(unreadable))
    assert done.returncode == 2
    assert done.stderr.splitlines() == [
        f"rcmlconf dissect: cannot read {tmp_path}/new\\nline.pcap: Input/output error"
    ]
