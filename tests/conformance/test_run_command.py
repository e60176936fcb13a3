"""`rcmlconf run` and `rcmlconf cases` as a user runs them: real processes, exit statuses, files."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

from support.processes import COMMAND, free_pair, run_command, wait_listening
from support.report_schemas import assert_junit_valid


def test_run_on_the_embedded_reference_writes_junit_json_and_captures(tmp_path: Path) -> None:
    junit, report, captures = tmp_path / "r.xml", tmp_path / "r.json", tmp_path / "pcaps"
    done = run_command(
        "run",
        "--only",
        "rctp/msg/*",
        "--junit",
        str(junit),
        "--json",
        str(report),
        "--capture",
        str(captures),
    )
    assert done.returncode == 0, done.stderr
    assert "the embedded reference" in done.stderr
    assert_junit_valid(junit)
    found = json.loads(report.read_text())
    assert found["results"]
    assert {r["verdict"] for r in found["results"]} == {"pass"}
    assert {p.name for p in captures.iterdir()} >= {"rctp_msg_connect.pcap"}


def test_a_target_that_is_not_there_is_an_error_not_a_failure(tmp_path: Path) -> None:
    """Found before any case runs: one line, status 2, and no case reported as failed."""
    done = run_command("run", "--target", "127.0.0.1:9", "--only", "rctp/msg/connect")
    assert done.returncode == 2, done.stderr
    assert done.stderr.splitlines() == [
        "rcmlconf run: cannot reach --target 127.0.0.1:9 (RCTP over TCP): connection"
        " refused; is the target running, on that port?"
    ]
    assert "fail" not in done.stdout


def test_usage_errors_exit_2_with_a_reason(tmp_path: Path) -> None:
    bad_ics = tmp_path / "ics.toml"
    bad_ics.write_text("[features]\nteleport = true\n")
    for args, reason in [
        (["--only", "nothing/*"], "no case matches"),
        (["--ics", str(bad_ics)], "unknown feature teleport"),
        (["--impair", "loss=200%"], "loss"),
        (["--rsp-target", "127.0.0.1"], "needs the robot's --model"),
    ]:
        done = run_command("run", *args)
        assert done.returncode == 2, (args, done.stderr)
        assert reason in done.stderr, (args, done.stderr)
        assert "Traceback" not in done.stderr


def test_cases_lists_and_the_matrix_covers(tmp_path: Path) -> None:
    listed = run_command("cases", "--format", "json")
    assert listed.returncode == 0, listed.stderr
    by_case = {c["id"]: c for c in json.loads(listed.stdout)}
    assert not by_case["rctp/msg/unknown-method"]["exclusive"]
    assert by_case["rctp/session/peer-floors"]["exclusive"]  # it runs alone, after the rest
    rows = run_command("cases", "--matrix", "--format", "json")
    assert rows.returncode == 0, rows.stderr
    by_id = {r["requirement"]: r for r in json.loads(rows.stdout)}
    assert "rctp/msg/unknown-method" in by_id["R-RCTP-9"]["cases"]
    assert by_id["R-RCML-7"]["validate"]


def test_role_client_tests_a_client_that_loops_over_the_case_list(tmp_path: Path) -> None:
    """The harness listens; the reference client (standing in for the user's) fetches the case
    list and runs D-RCTP-31's scenario on each URL in turn, as a client author's loop would."""
    report = tmp_path / "r.json"
    port = free_pair()
    # Three cases: one of the server's own requests, one of the requests, one of the stream.
    chosen = ["rctp/client/answers-bye", "rctp/client/cseq-numbering", "rctp/client/stream-echo"]
    args = ["run", "--role", "client", "--listen", str(port)]
    process = subprocess.Popen(
        [*COMMAND, *args, *(f"--only={c}" for c in chosen), "--json", str(report)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        wait_listening(port + 1)
        client = run_command("client", f"http://127.0.0.1:{port + 1}/cases", "scenario")
        assert client.returncode == 0, client.stderr
        out, err = process.communicate(timeout=60)
    finally:
        process.kill()
    assert process.returncode == 0, out + err
    verdicts = {r["case"]: r["verdict"] for r in json.loads(report.read_text())["results"]}
    assert verdicts == dict.fromkeys(chosen, "pass")
