"""The reference implementation run as an external target, as a user runs rcmlconf against theirs:
a process of its own, reached only through its address."""

from __future__ import annotations

import json
from pathlib import Path

from support.processes import free_pair, run_command, running

from rcmlconf.conformance.targets import REFERENCE_RCML, REFERENCE_RMODEL


def test_one_external_robot_serves_the_robot_cases_in_turn(tmp_path: Path) -> None:
    """A robot serves one session at a time (D-RSP-12), so the robot cases of a run take it in
    turn; a case's clock starts when it has the robot, not while it waits for it. Before, most of
    the header cases failed with 'the case did not finish within 5 s' and an empty exchange."""
    report = tmp_path / "report.json"
    with running(tmp_path, "robot", str(REFERENCE_RMODEL), "--port", "0") as robot:
        done = run_command(
            "run",
            "--rsp-target",
            f"127.0.0.1:{robot.ready['port']}",
            "--model",
            str(REFERENCE_RMODEL),
            "--only",
            "rsp/[hmp]*",  # header, map, motion, payload
            "--json",
            str(report),
        )
    results = json.loads(report.read_text())["results"]
    assert len(results) >= 20  # in turn, they take longer than any one case's 5 s timeout
    # CUBO has no monitored effector that holds on link loss (D-RSP-8): that case does not apply.
    verdicts = {r["case"]: r["verdict"] for r in results}
    assert verdicts.pop("rsp/motion/link-loss-holds") == "not applicable", done.stdout
    assert set(verdicts.values()) == {"pass"}, done.stdout
    assert done.returncode == 0


def test_the_reference_server_as_an_external_target_fails_nothing(tmp_path: Path) -> None:
    """Every server case, at default settings, against `rcmlconf serve` reached by its address
    alone (the RCML from its files, D-RCTP-29): no fail, no error; the cases that wait out its
    60 s session timeout are inconclusive and say how to wait for it. Its files are on the port
    after RCTP's, where D-RCTP-29 puts them and the rctp/files cases look."""
    report = tmp_path / "report.json"
    with running(tmp_path, "serve", str(REFERENCE_RCML), "--port", str(free_pair())) as up:
        port = up.rctp_port
        target = ["--target", f"127.0.0.1:{port}", "--rcml", str(REFERENCE_RCML)]
        done = run_command("run", *target, "--json", str(report))
    results = json.loads(report.read_text())["results"]
    verdicts = {r["verdict"] for r in results}
    assert len(results) > 150
    assert verdicts <= {"pass", "inconclusive", "not applicable"}, done.stdout
    unsure = [r for r in results if r["verdict"] == "inconclusive"]
    assert all("--session-wait 60" in r["reason"] for r in unsure), unsure
    assert done.returncode == 0
