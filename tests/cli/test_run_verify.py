"""`rcmlconf run --verify N` as a user runs it: each case N times, judged stable or not.

The reference is stable on these fast cases. The judgement of an unstable case is tested over
hand-made results (tests/conformance/test_stability.py).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from lxml import etree
from support.processes import run_command
from support.report_schemas import assert_junit_valid

from rcmlconf.cli.run import run, run_settings

FAST = ("rctp/msg/unsupported-content-type", "rctp/msg/wrong-version", "rctp/msg/unknown-field")


def parsed(*args: str) -> dict[str, Any]:
    return dict(run.make_context("run", list(args)).params)


def test_verify_runs_each_case_n_times_and_finds_the_reference_stable(tmp_path: Path) -> None:
    report, junit = tmp_path / "run.json", tmp_path / "run.xml"
    chosen = [arg for case in FAST for arg in ("--only", case)]
    done = run_command(
        "run", "--verify", "3", *chosen, "--json", str(report), "--junit", str(junit)
    )
    assert done.returncode == 0, done.stderr
    assert done.stderr.splitlines()[-1].endswith(": 9 results: 9 pass; 0 unstable")
    assert "UNSTABLE" not in done.stdout
    found = json.loads(report.read_text())  # run_command validated it against the schema
    assert found["settings"]["verify"] == found["settings"]["repeat"] == 3
    assert found["unstable"] == []
    assert sorted((r["case"], r["run"]) for r in found["results"]) == sorted(
        (case, run) for case in FAST for run in (1, 2, 3)
    )
    assert_junit_valid(junit)
    assert not etree.parse(str(junit)).findall(".//failure")


def test_verify_without_n_runs_each_case_ten_times() -> None:
    settings = run_settings(parsed("--verify", "--only", FAST[0]))
    assert (settings.verify, settings.runs, settings.only) == (10, 10, (FAST[0],))
    assert run_settings(parsed("--verify=4")).runs == 4
    assert run_settings(parsed("--repeat", "5")).runs == 5
    assert run_settings(parsed()).verify is None


def test_verify_with_repeat_is_a_usage_error_of_one_line() -> None:
    for args in (("--verify", "3", "--repeat", "2"), ("--repeat", "1", "--verify")):
        done = run_command("run", *args, "--only", FAST[0])
        assert done.returncode == 2, done.stderr
        errors = [line for line in done.stderr.splitlines() if line.startswith("Error:")]
        assert errors == ["Error: --verify N runs each case N times: leave out --repeat"]


def test_verify_needs_at_least_two_runs() -> None:
    done = run_command("run", "--verify", "1")
    assert done.returncode == 2
    assert "--verify" in done.stderr


def test_the_help_says_what_verify_does_with_an_example() -> None:
    text = " ".join(run_command("run", "--help").stdout.split())
    assert "--verify [N] Run each case N times (10 if no N)" in text
    assert "rcmlconf run --verify 20 --only 'rsp/local/*'" in text
