"""The `rcmlconf-validate` hook of .pre-commit-hooks.yaml, as pre-commit runs it for a user:
`pre-commit try-repo` on this repository, from a scratch repository of RCML files (pre-commit
installs rcmlconf into a hook environment of its own, as it would from the repository's URL)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import yaml
from support.xml_vectors import XML_VECTORS

ROOT = Path(__file__).parents[2]
#: Installing the hook's environment (a virtualenv, rcmlconf and its dependencies) takes time.
INSTALL_BOUND = 600


def pre_commit(where: Path, home: Path, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "pre_commit", "try-repo", str(ROOT), "rcmlconf-validate", *args],
        cwd=where,
        env={**os.environ, "PRE_COMMIT_HOME": str(home), "PRE_COMMIT_COLOR": "never"},
        capture_output=True,
        text=True,
        timeout=INSTALL_BOUND,
        check=False,
    )


def test_the_hook_checks_the_robot_files_and_only_them(tmp_path: Path) -> None:
    repository = tmp_path / "robots"
    repository.mkdir()
    (repository / "good.rcml").write_bytes((XML_VECTORS / "valid" / "deep.rcml").read_bytes())
    broken = (XML_VECTORS / "invalid" / "appendix-a-as-printed.rcml").read_bytes()
    (repository / "bad.rcml").write_bytes(broken)
    (repository / "notes.txt").write_text("not a robot\n")
    subprocess.run(["git", "init", "-q"], cwd=repository, check=True, timeout=60)
    subprocess.run(["git", "add", "."], cwd=repository, check=True, timeout=60)
    home = tmp_path / "pre-commit"
    passed = pre_commit(repository, home, "--files", "good.rcml", "notes.txt")
    assert passed.returncode == 0, passed.stdout + passed.stderr
    assert "rcmlconf validate" in passed.stdout
    assert "Passed" in passed.stdout
    failed = pre_commit(repository, home, "--all-files")
    assert failed.returncode == 1, failed.stdout + failed.stderr
    assert "bad.rcml:21:14: error: [R-XML-1]" in failed.stdout
    assert "notes.txt" not in failed.stdout
    assert "2 files checked: 1 invalid" in failed.stdout


def test_the_hook_file_names_the_three_languages() -> None:
    (hook,) = yaml.safe_load((ROOT / ".pre-commit-hooks.yaml").read_text())
    assert hook["id"] == "rcmlconf-validate"
    assert hook["entry"] == "rcmlconf validate"
    assert hook["language"] == "python"
    assert hook["files"] == r"\.(rcml|rxid|rmodel)$"
