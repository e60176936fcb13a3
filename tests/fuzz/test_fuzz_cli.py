"""`rcmlconf fuzz` as a user runs it, against the embedded reference: a real server process, real
sockets. A fault of the reference is found, minimised, and replays; the correct reference gives
no finding; a campaign resumes."""

from __future__ import annotations

import json
import shlex
import shutil
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

from support.fuzzing import BOUND, fuzz, valid
from support.processes import COMMAND, free_port, wait_listening

from rcmlconf.conformance.targets import REFERENCE_RMODEL


def test_the_reference_gives_no_finding_and_every_file_is_written(tmp_path: Path) -> None:
    out = tmp_path / "run"
    done = fuzz("--seconds", "4", "--out", str(out), "--junit", str(tmp_path / "f.xml"))
    assert done.returncode == 0, done.stderr
    report = json.loads((out / "report.json").read_text())
    valid(report, "fuzz-report.schema.json")
    assert report["findings"] == []
    assert report["cases"] > 20
    assert report["states_reached"] == 8
    assert report["timeline"][-1][1:3] == [report["cases"], 8]  # the end: every case, state
    assert {"state.json", "states.dot"} <= {p.name for p in out.iterdir()}
    if shutil.which("dot"):  # Graphviz (.ci/run installs it): the map drawn too
        assert (out / "states.png").read_bytes().startswith(b"\x89PNG\r\n\x1a\n")
    assert 'failures="0"' in (tmp_path / "f.xml").read_text()
    # --resume goes on from the state: the count of cases grows.
    again = fuzz("--cases", "10", "--resume", str(out))
    assert again.returncode == 0, again.stderr
    assert "resuming" in again.stderr
    assert json.loads((out / "report.json").read_text())["cases"] == report["cases"] + 10


def test_a_fault_of_the_reference_is_found_minimised_and_replayed(tmp_path: Path) -> None:
    out = tmp_path / "run"
    done = fuzz("--fault", "version-ignored", "--seconds", "10", "--out", str(out), "--seed", "3")
    assert done.returncode == 1, done.stderr
    report = json.loads((out / "report.json").read_text())
    found = [f for f in report["findings"] if f["requirement"] == "R-RCTP-10"]
    assert found, report["findings"]
    finding = out / found[0]["file"]
    item = json.loads(finding.read_text())
    valid(item, "fuzz-finding.schema.json")
    valid(report, "fuzz-report.schema.json")
    assert item["oracle"] == "violation"
    assert item["minimised"]
    assert item["stable"]["fired"] >= 1
    assert len(item["case"]["steps"]) <= len(item["original"]["steps"])
    assert finding.with_suffix(".pcap").stat().st_size > 24
    # It reproduces where the fault is, and not where it is not.
    assert fuzz("replay", str(finding), "--fault", "version-ignored").returncode == 1
    fixed = fuzz("replay", str(finding))
    assert fixed.returncode == 0, fixed.stderr
    assert "did not reproduce" in fixed.stderr


def test_the_reference_robot_gives_no_finding(tmp_path: Path) -> None:
    out = tmp_path / "robot"
    done = fuzz("--model", str(REFERENCE_RMODEL), "--seconds", "4", "--out", str(out))
    assert done.returncode == 0, done.stderr
    report = json.loads((out / "report.json").read_text())
    valid(report, "fuzz-report.schema.json")
    assert report["settings"]["target"]["role"] == "robot"
    assert report["states_reached"] == 5
    assert report["cases"] > 10


def test_a_target_that_cannot_be_restarted_ends_the_campaign_with_its_findings(
    tmp_path: Path,
) -> None:
    """SIGKILL takes the target 2 s in (a crash finding; SIGTERM would let it shut down as it
    should); its restart exits before it listens. The campaign stops there, and still writes
    the finding and the report (exit 1, not 2)."""
    foreign = Path(__file__).resolve().parents[1] / "foreign" / "rctp_server"
    port = free_port()
    server = shlex.join(
        [sys.executable, str(foreign / "main.py"), "--port", str(port), "--http-port",
         str(free_port())]
    )  # fmt: skip
    mark = tmp_path / "started"
    script = f"test -e {mark} && exit 3; touch {mark}; (sleep 2; kill -9 $$) & exec {server}"
    out = tmp_path / "run"
    done = fuzz(
        "--target", f"127.0.0.1:{port}", "--rcml", str(foreign / "robot.rcml"),
        "--target-command", shlex.join(["sh", "-c", script]), "--seconds", "30",
        "--out", str(out),
    )  # fmt: skip
    assert done.returncode == 1, done.stderr
    assert "Traceback" not in done.stderr
    report = json.loads((out / "report.json").read_text())
    valid(report, "fuzz-report.schema.json")
    assert "could not be restarted" in report["stopped"]
    assert "exited with status 3" in report["stopped"]
    assert [f["oracle"] for f in report["findings"]] == ["crash"]
    assert (out / report["findings"][0]["file"]).exists()
    assert report["seconds"] < 20


def test_a_killed_fuzzer_leaves_no_target_behind(tmp_path: Path) -> None:
    """SIGKILL gives the fuzzer no time to stop its target (a CI job's timeout does that):
    the target must end by itself, or it keeps its port and the next job cannot start."""
    foreign = Path(__file__).resolve().parents[1] / "foreign" / "rctp_server"
    port = free_port()
    pid_file = tmp_path / "pid"
    server = shlex.join(
        [sys.executable, str(foreign / "main.py"), "--port", str(port), "--http-port",
         str(free_port())]
    )  # fmt: skip
    script = f"echo $$ > {pid_file}; exec {server}"
    fuzzer = subprocess.Popen(
        [*COMMAND, "fuzz", "--target", f"127.0.0.1:{port}", "--rcml", str(foreign / "robot.rcml"),
         "--target-command", shlex.join(["sh", "-c", script]), "--seconds", "60",
         "--out", str(tmp_path / "run")],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
    )  # fmt: skip
    try:
        wait_listening(port, BOUND)  # the fuzzer's cases start once it listens
        assert fuzzer.poll() is None, "the fuzzer ended early"
        target = int(pid_file.read_text())
        fuzzer.send_signal(signal.SIGKILL)
        fuzzer.wait(BOUND)
        deadline = time.monotonic() + BOUND
        while _alive(target):
            assert time.monotonic() < deadline, "the target outlived its fuzzer"
            time.sleep(0.05)
    finally:
        fuzzer.kill()
        fuzzer.wait(BOUND)


def _alive(pid: int) -> bool:
    """Whether `pid` runs (a zombie has ended: the init process reaps it)."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat[stat.rindex(")") + 2] != "Z"


def test_usage_errors_exit_2_with_one_line(tmp_path: Path) -> None:
    for wrong, said in [
        (("--role", "local", "--client-command", "x {url}"), "--role local needs --model"),
        (
            ("--role", "local", "--model", str(REFERENCE_RMODEL), "--client-command", "x"),
            "needs {url}",
        ),
        (("--role", "client", "--target", "127.0.0.1:1"), "leave out --target"),
        (("--role", "client", "--client-command", "my-client"), "needs {url}"),
        (("--role", "client", "--target-command", "x"), "--client-command"),
        (("--state", "nowhere"), "--state 'nowhere': this target's states are connected,"),
        (("--kind", "nothing"), "--kind 'nothing': the kinds of those states are"),
    ]:
        done = fuzz(*wrong, "--seconds", "1", "--out", str(tmp_path))
        assert done.returncode == 2, (wrong, done.stderr)
        assert said in done.stderr, (wrong, done.stderr)
        assert "Traceback" not in done.stderr
    with socket.socket() as taken, socket.socket(type=socket.SOCK_DGRAM) as datagrams:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        datagrams.bind(("127.0.0.1", port))
        for role in (["--role", "client"], ["--role", "local", "--model", str(REFERENCE_RMODEL)]):
            done = fuzz(*role, "--listen", f"127.0.0.1:{port}", "--out", str(tmp_path))
            assert done.returncode == 2, (role, done.stderr)
            assert f"cannot listen on 127.0.0.1:{port} (--listen): " in done.stderr, done.stderr
            assert "internal error" not in done.stderr
    bad = tmp_path / "finding.json"
    bad.write_text("{}")
    replayed = fuzz("replay", str(bad))
    assert replayed.returncode == 2
    assert "Traceback" not in replayed.stderr
    assert "not a finding" in replayed.stderr
