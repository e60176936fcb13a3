"""`run --target` against servers that reset, ignore or stop taking connections
(tests/support/hostile_resets.py), and `run --rsp-target` against a robot that answers nothing:
each case that waited on the target fails for what it did, never with a harness fault or a
network error; a target that answers nothing is given up on after IN_A_ROW cases, so the run
ends in a second or two, not a timeout a case."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path
from typing import Any

from support.hostile_files import hostile_robot
from support.hostile_resets import hostile
from support.processes import free_port, run_command

from rcmlconf.cli.run_target import server_problem
from rcmlconf.conformance.giveup import NOT_RUN
from rcmlconf.conformance.probes.lost import RESET
from rcmlconf.conformance.targets import REFERENCE_RCML, REFERENCE_RMODEL
from rcmlconf.validate.validator import load_robot_model

#: Cases that send their first request at once: the request/answer ones of rctp/msg.
MSG = "rctp/msg/[a-c]*"


def judged(port: int, report: Path, *options: str) -> tuple[subprocess.CompletedProcess[str], Any]:
    """`rcmlconf run --target 127.0.0.1:PORT` with the reference's RCML, and its results."""
    target = ["--target", f"127.0.0.1:{port}", "--rcml", str(REFERENCE_RCML)]
    done = run_command("run", *target, "--json", str(report), *options)
    assert "harness fault" not in done.stdout + done.stderr, done.stdout
    assert "network error" not in done.stdout + done.stderr, done.stdout
    return done, json.loads(report.read_text())["results"]


def given_up(done: subprocess.CompletedProcess[str], port: int, why: str) -> None:
    """The summary says once that the rest were not run, and why."""
    said = [line for line in done.stderr.splitlines() if line.startswith("gave up on")]
    assert len(said) == 1, done.stderr
    assert said[0].startswith(f"gave up on 127.0.0.1:{port}: "), said
    assert why in said[0], said


def test_a_target_that_resets_every_connection_fails_and_is_given_up_on(tmp_path: Path) -> None:
    """The whole suite. Before: 170 errors 'cannot connect to ...: [Errno 104]', a harness
    fault (TypeError), or status 2 'connection reset' from the reachability check."""
    with hostile("reset") as port:
        done, results = judged(port, tmp_path / "r.json")
    verdicts = {r["verdict"] for r in results}
    assert verdicts <= {"fail", "inconclusive", "not applicable"}, done.stdout
    failed = [r for r in results if r["verdict"] == "fail" and r["actual"] == RESET]
    assert failed, done.stdout
    assert all(r["requirement"] for r in failed), done.stdout
    not_run = [r for r in results if r["reason"].startswith(NOT_RUN)]
    assert len(not_run) > len(results) / 2
    assert {r["reason"] for r in not_run} == {
        f"{NOT_RUN}the target reset every connection of the 8 cases before"
    }
    given_up(done, port, f"{len(not_run)} cases {NOT_RUN}")
    assert done.returncode == 1  # its cases failed


def test_a_reset_after_the_request_fails_the_answer_it_waited_for(tmp_path: Path) -> None:
    """Before: 'the connection closed without one', a reset taken for a plain close."""
    with hostile("reset-after-request") as port:
        done, results = judged(port, tmp_path / "r.json", "--only", MSG)
    ran = [r for r in results if not r["reason"].startswith(NOT_RUN)]
    assert {r["verdict"] for r in ran} == {"fail"}, done.stdout
    assert {r["actual"] for r in ran} == {RESET}, done.stdout
    assert done.returncode == 1


def test_a_silent_target_is_given_up_on(tmp_path: Path) -> None:
    """It takes every connection and never sends a byte: each case would wait out its answer."""
    with hostile("silent") as port:
        options = ("--only", "rctp/msg/*", "--timeout-scale", "0.1")
        done, results = judged(port, tmp_path / "r.json", *options)
    assert {r["verdict"] for r in results} == {"fail", "inconclusive"}, done.stdout
    given_up(done, port, "not run: the target sent nothing on any connection of the 8 cases")
    assert done.returncode == 1


def test_a_target_that_stops_taking_connections_is_given_up_on(tmp_path: Path) -> None:
    """It answers its first connections (the reachability check's and three cases', one case
    at a time), then refuses: those cases are errors (nothing listens), the rest are not run."""
    with hostile("dies", after=4) as port:
        options = ("--only", "rctp/msg/*", "--concurrency", "1", "--timeout-scale", "0.2")
        done, results = judged(port, tmp_path / "r.json", *options)
    errors = [r for r in results if r["verdict"] == "error"]
    assert errors, done.stdout
    assert all("connection refused" in r["reason"] for r in errors), done.stdout
    # A connection made as the listener closes is reset, not refused: on a busy machine the
    # harness can connect in that moment, so "7 refused, 1 reset" is the same verdict.
    given_up(done, port, "of the 8 cases before")
    given_up(done, port, "having answered before: it stopped")
    assert "refused" in done.stderr, done.stderr
    assert done.returncode != 0


def test_the_reachability_check_takes_a_reset_for_a_target_that_is_there() -> None:
    """A reset after the handshake is a target that is there; a refused connection is not.
    Before, the check raced the reset and said 'connection reset' in some runs."""
    with hostile("reset") as port:
        assert [server_problem(("127.0.0.1", port), 1.0) for _ in range(20)] == [None] * 20
    refused = server_problem(("127.0.0.1", free_port()), 1.0)
    assert refused is not None
    assert refused.startswith("connection refused")


def test_a_robot_that_answers_nothing_fails_welcome_and_is_given_up_on(tmp_path: Path) -> None:
    """Each robot case waited for an answer to its HELLO, one after another: 140 s for the whole
    suite. The basic case runs first and fails (R-RSP-20); 8 cases later the rest are not run."""
    report = tmp_path / "r.json"
    with hostile_robot(load_robot_model(REFERENCE_RMODEL), "silent") as port:
        target = ["--rsp-target", f"127.0.0.1:{port}", "--model", str(REFERENCE_RMODEL)]
        options = ["--only", "rsp/session/*", "--timeout-scale", "0.1", "--json", str(report)]
        done = run_command("run", *target, *options)
    results = {r["case"]: r for r in json.loads(report.read_text())["results"]}
    welcome = results["rsp/session/welcome"]
    assert (welcome["verdict"], welcome["requirement"]) == ("fail", "R-RSP-20"), done.stdout
    given_up(done, port, "not run: the target answered no datagram of the 8 cases before")
    verdicts = {r["verdict"] for r in results.values()}
    assert verdicts <= {"fail", "inconclusive", "not applicable"}, done.stdout
    assert done.returncode == 1
