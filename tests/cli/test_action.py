"""action.yml, the composite GitHub Action: its shape as GitHub reads it, its steps the commands
README shows, and those commands run as the runner would run them (bash, the inputs as
variables, rcmlconf installed), on real files and the embedded reference."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path
from typing import Any

import yaml
from support.case_counts import MSG_CASES
from support.report_schemas import assert_junit_valid
from support.xml_vectors import XML_VECTORS

ROOT = Path(__file__).parents[2]
ACTION: dict[str, Any] = yaml.safe_load((ROOT / "action.yml").read_text())
STEPS: list[dict[str, Any]] = ACTION["runs"]["steps"]
#: `${{ inputs.NAME }}`, an expression GitHub replaces before the step runs.
INPUT = re.compile(r"\$\{\{\s*inputs\.([a-z-]+)\s*\}\}")


def test_the_action_is_a_composite_of_bash_steps_fed_by_its_inputs() -> None:
    assert ACTION["name"]
    assert ACTION["description"]
    assert ACTION["runs"]["using"] == "composite"
    inputs = ACTION["inputs"]
    assert {"command", "paths", "target", "rcml", "baseline", "junit"} <= set(inputs)
    assert all(spec["description"] and "default" in spec for spec in inputs.values())
    assert STEPS[0]["uses"].startswith("actions/setup-python@")
    used: set[str] = set()
    for step in STEPS:
        text = yaml.safe_dump(step)
        used.update(INPUT.findall(text))
        if "run" in step:
            assert step["shell"] == "bash"
            # An input pasted into a script would be a script injection: variables only.
            assert "${{" not in step["run"], step["run"]
    assert used == set(inputs) - {"command"}
    conditions = {step.get("if") for step in STEPS}
    assert {"inputs.command == 'validate'", "inputs.command == 'run'"} <= conditions


def test_the_steps_run_the_commands_readme_shows() -> None:
    readme = (ROOT / "README.md").read_text()
    shown = readme.split("the steps run, after `actions/setup-python`:\n\n```bash\n", 1)[1]
    shown = shown.split("```", 1)[0]
    assert shown.splitlines() == [step["run"] for step in STEPS if "run" in step]


def step(name: str, **given: str) -> subprocess.CompletedProcess[str]:
    """The step named `name` as the runner runs it: bash, its `env` with each input's value
    (`given`, else its default), from the repository's root."""
    (found,) = (s for s in STEPS if s.get("name") == name)
    inputs = {key: str(spec["default"]) for key, spec in ACTION["inputs"].items()}
    inputs.update({key.replace("_", "-"): value for key, value in given.items()})
    env = {key: INPUT.sub(lambda m: inputs[m[1]], value) for key, value in found["env"].items()}
    path = f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}"  # rcmlconf's
    return subprocess.run(
        ["bash", "-eo", "pipefail", "-c", found["run"]],
        cwd=ROOT,
        env={**os.environ, "PATH": path, **env},
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )


def test_the_validate_step_annotates_what_is_wrong() -> None:
    good = step("rcmlconf validate", paths=str(XML_VECTORS / "valid" / "deep.rcml"))
    assert good.returncode == 0, good.stderr
    bad = XML_VECTORS / "invalid" / "appendix-a-as-printed.rcml"
    found = step("rcmlconf validate", paths=f"{bad} {XML_VECTORS / 'valid' / 'deep.rcml'}")
    assert found.returncode == 1
    assert found.stdout.startswith(f"::error file={bad},line=21,col=14,title=R-XML-1::")


def test_the_run_step_writes_a_junit_report(tmp_path: Path) -> None:
    report = tmp_path / "rcmlconf.xml"
    done = step("rcmlconf run", command="run", only="rctp/msg/*", junit=str(report))
    assert done.returncode == 0, done.stderr
    assert f"{MSG_CASES} results: {MSG_CASES} pass" in done.stderr
    assert_junit_valid(report)
