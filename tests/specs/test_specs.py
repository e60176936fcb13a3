"""specs/ holds code, tests and vectors to its word, and they hold it to theirs."""

from __future__ import annotations

import re
from pathlib import Path

from support.xml_vectors import xml_vectors

from rcmlconf.specs import decisions, requirements, specs_dir

PACKAGE = Path(__file__).parents[2] / "rcmlconf"
RULE = re.compile(r"\bR-[A-Z]+-\d+\b")
DECISION = re.compile(r"\bD-[A-Z]+-\d+\b")

#: `validate` requirements shown by a generated test instead of a vector, and why.
GENERATED = {
    "R-XML-5": "a 16 MiB document does not belong in the repository: tests/markup makes one",
}


def test_requirements_are_numbered_without_gaps() -> None:
    by_prefix: dict[str, list[int]] = {}
    for rid in requirements():
        prefix, number = rid.rsplit("-", 1)
        by_prefix.setdefault(prefix, []).append(int(number))
    for prefix, numbers in by_prefix.items():
        assert sorted(numbers) == list(range(1, len(numbers) + 1)), prefix


def test_every_rule_the_code_names_is_a_requirement() -> None:
    known = requirements()
    for path in PACKAGE.rglob("*.py"):
        for rule in RULE.findall(path.read_text(encoding="utf-8")):
            assert rule in known, f"{path.relative_to(PACKAGE.parent)} names {rule}"


def test_every_reference_in_specs_and_code_exists() -> None:
    rules, made = requirements(), decisions()
    texts = list(specs_dir().glob("*.md")) + list(PACKAGE.rglob("*.py"))
    for path in texts:
        text = path.read_text(encoding="utf-8")
        for rule in RULE.findall(text):
            assert rule in rules, f"{path.name} refers to {rule}"
        for decision in DECISION.findall(text):
            assert decision in made, f"{path.name} refers to {decision}"


def test_every_validated_requirement_is_shown_by_a_vector() -> None:
    shown = {rule for vector in xml_vectors() for *_, rule in vector.expected}
    for requirement in requirements().values():
        if "validate" in requirement.checks and requirement.id not in GENERATED:
            assert requirement.id in shown, f"no vector shows {requirement.id}"


def test_requirements_without_validate_are_not_reported_by_it() -> None:
    shown = {rule for vector in xml_vectors() for *_, rule in vector.expected}
    for rule in shown:
        assert "validate" in requirements()[rule].checks, rule


def test_level_keyword_appears_in_the_text() -> None:
    for requirement in requirements().values():
        assert requirement.level in requirement.text, requirement.id
