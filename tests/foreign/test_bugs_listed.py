"""Each foreign implementation lists its planted robustness bugs (`--list-bugs`), the ones the
fuzzer's tests must find, and refuses a name it does not know (`--bug`, issue 29)."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent
IMPLEMENTATIONS = ["rctp_server", "rsp_robot", "rctp_client", "rsp_local"]
ORACLES = {"crash", "hang", "violation", "leak"}
SHALLOW = {"connected", "any"}


def _run(name: str, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, str(HERE / name / "main.py"), *args],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )


def _bugs(name: str) -> list[list[str]]:
    done = _run(name, "--list-bugs")
    assert done.returncode == 0, done.stderr
    return [line.split("\t") for line in done.stdout.splitlines()]


@pytest.mark.parametrize("name", IMPLEMENTATIONS)
def test_bugs_are_listed(name: str) -> None:
    rows = _bugs(name)
    assert len(rows) >= 5, rows
    for row in rows:
        assert len(row) == 5, row
        bug, oracle, state, what, stream = row
        assert re.fullmatch(r"[a-z0-9]+(-[a-z0-9]+)*", bug), row
        assert oracle in ORACLES, row
        assert re.fullmatch(r"[a-z]+( [a-z]+)*", state), row
        assert what.strip() == what, row
        assert len(what) > 20, row
        assert stream in ("data", "control"), row
    assert len({row[0] for row in rows}) == len(rows)
    assert sum(row[2] not in SHALLOW for row in rows) >= 2, "two deep in state"
    assert any(row[4] == "data" for row in rows), "one on the data stream"
    oracles = {row[1] for row in rows}
    assert "crash" in oracles, oracles
    assert oracles & {"hang", "leak", "violation"}, oracles


@pytest.mark.parametrize("name", IMPLEMENTATIONS)
def test_an_unknown_bug_is_a_usage_error(name: str) -> None:
    done = _run(name, "--bug", "no-such-bug", "--list-bugs")
    assert done.returncode == 2, (done.returncode, done.stderr)
    assert "no-such-bug" in done.stderr


def test_the_four_oracles_are_covered() -> None:
    assert {row[1] for name in IMPLEMENTATIONS for row in _bugs(name)} == ORACLES
