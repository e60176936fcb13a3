"""`rcmlconf fuzz` finds the robustness bugs planted in the implementations of tests/foreign/
(`--bug NAME`), with a fixed seed and a short budget, as a user runs it: the fuzzer starts the
implementation itself (--target-command) and keeps its exit status and stderr.
"""

from __future__ import annotations

import json
import shlex
import subprocess
import sys
from pathlib import Path

import pytest
from support.processes import COMMAND, free_port

FOREIGN = Path(__file__).resolve().parent
#: Each budget ends well within this.
BOUND = 180

#: (folder, bug, oracle, seconds): bugs a short campaign must find.
FOUND = [
    ("rctp_server", "content-length-sign", "crash", 40),
    ("rsp_robot", "map-padding-crash", "crash", 30),
]


def campaign(folder: str, bug: str | None, seconds: int, out: Path) -> dict[str, object]:
    port = free_port()
    main = FOREIGN / folder / "main.py"
    if folder == "rctp_server":
        started = [sys.executable, str(main), "--port", str(port), "--http-port", str(free_port())]
        target = ["--target", f"127.0.0.1:{port}", "--rcml", str(FOREIGN / folder / "robot.rcml")]
    else:
        started = [sys.executable, str(main), "--port", str(port)]
        target = [
            "--rsp-target",
            f"127.0.0.1:{port}",
            "--model",
            str(FOREIGN / folder / "robot.rmodel"),
        ]
    if bug is not None:
        started += ["--bug", bug]
    done = subprocess.run(
        [*COMMAND, "fuzz", *target, "--target-command", shlex.join(started), "--seconds",
         str(seconds), "--seed", "1", "--out", str(out)],
        capture_output=True, text=True, timeout=BOUND, check=False,
    )  # fmt: skip
    assert done.returncode in (0, 1), done.stderr
    report: dict[str, object] = json.loads((out / "report.json").read_text())
    return report


@pytest.mark.parametrize(("folder", "bug", "oracle", "seconds"), FOUND)
def test_a_planted_bug_is_found(
    folder: str, bug: str, oracle: str, seconds: int, tmp_path: Path
) -> None:
    report = campaign(folder, bug, seconds, tmp_path)
    findings = report["findings"]
    assert isinstance(findings, list)
    fired = [f for f in findings if f["oracle"] == oracle]
    assert fired, findings
    finding = json.loads((tmp_path / fired[0]["file"]).read_text())
    assert "Traceback" in finding["target_output"]["stderr_tail"]
    assert finding["stable"]["fired"] >= 1


@pytest.mark.parametrize("folder", ["rctp_server", "rsp_robot"])
def test_a_correct_implementation_gives_no_finding(folder: str, tmp_path: Path) -> None:
    report = campaign(folder, None, 10, tmp_path)
    assert report["findings"] == []
