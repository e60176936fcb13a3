"""`rcmlconf fuzz --role client` (D-FUZZ-8) as a user runs it: the fuzzer plays the server to a
client it starts for each case, real processes on real sockets. The embedded reference client
gives no finding; a planted crash of the independent client is found, kept with the client's
stderr, and replays; a case of the correct client does not reproduce it."""

from __future__ import annotations

import json
import shlex
import sys
from pathlib import Path

from support.fuzzing import fuzz, valid

FOREIGN_CLIENT = Path(__file__).resolve().parent.parent / "foreign" / "rctp_client" / "main.py"


def client(*bug: str) -> str:
    return shlex.join([sys.executable, str(FOREIGN_CLIENT), "--url", "{url}", *bug])


def test_the_reference_client_gives_no_finding(tmp_path: Path) -> None:
    done = fuzz("--role", "client", "--cases", "14", "--seed", "3", "--out", str(tmp_path))
    assert done.returncode == 0, done.stderr
    report = json.loads((tmp_path / "report.json").read_text())
    valid(report, "fuzz-report.schema.json")
    assert report["findings"] == []
    assert report["cases"] == 14
    assert report["settings"]["target"]["role"] == "client"
    # The cells are drawn by weight, so which states 14 cases reach is the seed's; not one.
    assert report["states_reached"] >= 3, report["state_map"]


def test_a_planted_crash_is_found_kept_with_its_stderr_and_replayed(tmp_path: Path) -> None:
    out = tmp_path / "run"
    focus = ("--state", "connecting", "--kind", "answer-session")
    done = fuzz(
        "--role", "client", "--client-command", client("--bug", "session-timeout-crash"),
        *focus, "--seconds", "12", "--seed", "1", "--out", str(out),
    )  # fmt: skip
    assert done.returncode == 1, done.stderr
    report = json.loads((out / "report.json").read_text())
    assert (report["settings"]["states"], report["settings"]["kinds"]) == (
        ["connecting"],
        ["answer-session"],
    )
    crashes = [f for f in report["findings"] if f["oracle"] == "crash"]
    assert crashes, report["findings"]
    finding = json.loads((out / crashes[0]["file"]).read_text())
    valid(finding, "fuzz-finding.schema.json")
    assert finding["role"] == "client"
    assert finding["state"] == "connecting"
    assert finding["target_output"]["status"] == 1
    assert "Traceback" in finding["target_output"]["stderr_tail"]
    assert b"timeout=" in bytes.fromhex(finding["case"]["steps"][0]["hex"])
    path = str(out / crashes[0]["file"])
    again = fuzz("replay", path, "--role", "client", "--client-command", client("--bug",
                 "session-timeout-crash"))  # fmt: skip
    assert again.returncode == 1, again.stderr + again.stdout
    assert "reproduced: crash" in again.stderr + again.stdout
    correct = fuzz("replay", path, "--role", "client", "--client-command", client())
    assert correct.returncode == 0, correct.stderr + correct.stdout
    assert "did not reproduce" in correct.stderr + correct.stdout


def test_a_client_that_never_connects_misses_every_state_and_ends(tmp_path: Path) -> None:
    """A command that exits at once: every case misses its state; the campaign still ends with
    a report, and no finding (nothing was sent to judge)."""
    silent = shlex.join([sys.executable, "-c", "pass", "{url}"])
    done = fuzz("--role", "client", "--client-command", silent, "--cases", "3",
                "--connect-timeout", "0.5", "--out", str(tmp_path))  # fmt: skip
    assert done.returncode == 0, done.stderr
    report = json.loads((tmp_path / "report.json").read_text())
    assert report["cases"] == 3
    assert report["states_reached"] == 0
