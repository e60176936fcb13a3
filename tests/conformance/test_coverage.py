"""The matrix of `rcmlconf cases --matrix`: what covers each requirement, and the requirements
specs/ tags `unobservable` (no black-box case can check them) counted apart, with their reason,
never as covered and never as missing."""

from __future__ import annotations

import json
from pathlib import Path

from support.processes import run_command

from rcmlconf.conformance.coverage import UNOBSERVABLE, matrix
from rcmlconf.conformance.registry import all_cases
from rcmlconf.specs import requirements

SPEC = """# A spec

- **R-T-1** (MUST; unobservable) A screen MUST show it. Unobservable: only a person sees a
  screen.
- **R-T-2** (MUST) A server MUST answer.
- **R-T-3** (MUST; unobservable) A thing MUST be so.
- **R-T-4** (MUST; validate) A file MUST be valid.
"""


def test_an_unobservable_requirement_is_neither_covered_nor_missing(tmp_path: Path) -> None:
    (tmp_path / "t.md").write_text(SPEC)
    rows = {row.requirement.id: row for row in matrix([], requirements(tmp_path))}
    assert rows["R-T-1"].unobservable == "only a person sees a screen."
    assert rows["R-T-3"].unobservable == "specs/ gives no reason"
    assert [r for r, row in rows.items() if row.missing] == ["R-T-2"]
    assert [r for r, row in rows.items() if row.covered] == ["R-T-4"]


def test_every_unobservable_requirement_of_specs_says_why_and_no_case_claims_it() -> None:
    tagged = [r for r in requirements().values() if UNOBSERVABLE in r.checks]
    assert tagged
    named = {r for case in all_cases().values() for r in case.requirements}
    for requirement in tagged:
        assert "Unobservable: " in requirement.text, requirement.id
        assert requirement.id not in named, requirement.id


def test_the_matrix_shows_the_reason_and_strict_counts_only_what_a_case_could_check() -> None:
    rows = run_command("cases", "--matrix", "--format", "json")
    by_id = {r["requirement"]: r for r in json.loads(rows.stdout)}
    assert by_id["R-RXID-30"]["unobservable"].startswith("what a browser runs")
    assert by_id["R-RCTP-9"]["unobservable"] is None
    text = run_command("cases", "--matrix", "--strict")
    missing = [
        line.split()[0]
        for line in text.stdout.splitlines()
        if line.split()[1] == "MUST" and line.rstrip().endswith("UNCOVERED")  # MUST (NOT)
    ]
    assert "R-RXID-30" not in missing
    assert text.returncode == (1 if missing else 0)
    assert f"({len(missing)} of them MUST)" in text.stderr
