"""`run --target` against servers that reset connections (tests/support/hostile_resets.py): each
case that waited on the target fails for what it did (D-RCTP-1), never with a harness fault or a
network error."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path
from typing import Any

from support.hostile_resets import hostile
from support.processes import free_port, run_command

from rcmlconf.cli.run_target import server_problem
from rcmlconf.conformance.probes.lost import RESET
from rcmlconf.conformance.targets import REFERENCE_RCML

#: Cases that send their first request at once: the request/answer ones of rctp/msg.
MSG = "rctp/msg/[a-c]*"


def judged(port: int, report: Path, *options: str) -> tuple[subprocess.CompletedProcess[str], Any]:
    """`rcmlconf run --target 127.0.0.1:PORT` with the reference's RCML, and its results."""
    target = ["--target", f"127.0.0.1:{port}", "--rcml", str(REFERENCE_RCML)]
    done = run_command("run", *target, "--json", str(report), *options)
    assert "harness fault" not in done.stdout + done.stderr, done.stdout
    assert "network error" not in done.stdout + done.stderr, done.stdout
    return done, json.loads(report.read_text())["results"]


def test_a_target_that_resets_every_connection_fails(tmp_path: Path) -> None:
    """The whole suite. Before: 170 errors 'cannot connect to ...: [Errno 104]', a harness
    fault (TypeError), or status 2 'connection reset' from the reachability check."""
    with hostile("reset") as port:
        done, results = judged(port, tmp_path / "r.json")
    verdicts = {r["verdict"] for r in results}
    assert verdicts <= {"fail", "inconclusive", "not applicable"}, done.stdout
    failed = [r for r in results if r["verdict"] == "fail" and r["actual"] == RESET]
    assert len(failed) > len(results) / 2, done.stdout
    assert all(r["requirement"] for r in failed), done.stdout
    assert done.returncode == 1


def test_a_reset_after_the_request_fails_the_answer_it_waited_for(tmp_path: Path) -> None:
    """Before: 'the connection closed without one', a reset taken for a plain close."""
    with hostile("reset-after-request") as port:
        done, results = judged(port, tmp_path / "r.json", "--only", MSG)
    assert {r["verdict"] for r in results} == {"fail"}, done.stdout
    assert {r["actual"] for r in results} == {RESET}, done.stdout
    assert done.returncode == 1


def test_the_reachability_check_takes_a_reset_for_a_target_that_is_there() -> None:
    """A reset after the handshake is a target that is there; a refused connection is not.
    Before, the check raced the reset and said 'connection reset' in some runs."""
    with hostile("reset") as port:
        assert [server_problem(("127.0.0.1", port), 1.0) for _ in range(20)] == [None] * 20
    refused = server_problem(("127.0.0.1", free_port()), 1.0)
    assert refused is not None
    assert refused.startswith("connection refused")
