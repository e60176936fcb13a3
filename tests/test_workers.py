"""The test run's own set-up: pytest-xdist's `--dist loadgroup` (pyproject's addopts) keeps a
group's tests on one worker. The timed sweeps rely on it (tests/support/sweeps.py), and it has
failed silently before: on pytest 9.2 no test was grouped (pytest-dev/pytest-xdist#1386)."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

from support.processes import BOUND

GROUPED = """
import pytest

pytestmark = pytest.mark.xdist_group("together")


def test_one():
    pass


def test_two():
    pass
"""


def test_a_group_runs_on_one_worker(tmp_path: Path) -> None:
    (tmp_path / "test_grouped.py").write_text(GROUPED)
    (tmp_path / "pytest.ini").write_text("[pytest]\n")
    grouping = ["-n", "2", "--dist", "loadgroup"]  # as pyproject's addopts
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "pytest",
            *grouping,
            "-v",
            "-p",
            "no:cacheprovider",
            "test_grouped.py",
        ],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=BOUND,
        check=False,
    )
    assert done.returncode == 0, done.stdout + done.stderr
    ran = re.findall(r"\[(gw\d+)\] .*PASSED test_grouped\.py::(test_\w+)(@together)?", done.stdout)
    assert len(ran) == 2, done.stdout
    assert all(group for _, _, group in ran), f"not grouped:\n{done.stdout}"
    assert len({worker for worker, _, _ in ran}) == 1, done.stdout
