"""`rcmlconf fuzz --role local` (D-FUZZ-9) on the embedded reference local system, as a user
runs it: the fuzzer plays a robot of the model to `rcmlconf local --scenario`, started for each
case. The planted bugs of the independent local system are tests/foreign/test_fuzz_bugs.py's."""

from __future__ import annotations

import json
from pathlib import Path

from support.fuzzing import fuzz, valid

from rcmlconf.conformance.targets import REFERENCE_RMODEL


def test_the_reference_local_system_gives_no_finding(tmp_path: Path) -> None:
    done = fuzz("--role", "local", "--model", str(REFERENCE_RMODEL), "--cases", "8", "--seed",
                "2", "--out", str(tmp_path))  # fmt: skip
    assert done.returncode == 0, done.stderr
    report = json.loads((tmp_path / "report.json").read_text())
    valid(report, "fuzz-report.schema.json")
    assert report["findings"] == []
    assert report["cases"] == 8
    target = report["settings"]["target"]
    assert (target["role"], target["embedded"]) == ("local", True)
    assert report["states_reached"] >= 2, report["state_map"]
