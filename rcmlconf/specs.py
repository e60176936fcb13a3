"""The requirements of specs/, read from the documents themselves (specs/README.md, "Reading a
requirement"), so that code, tests and reports never keep a second copy.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

#: Where the documents are: beside the package in a checkout, inside it in a wheel.
_CANDIDATES = (
    Path(__file__).resolve().parent / "_specs",
    Path(__file__).resolve().parent.parent / "specs",
)
_BULLET = re.compile(
    r"^- \*\*(?P<id>R-[A-Z]+-\d+)\*\* \((?P<level>MUST NOT|MUST|SHOULD NOT|SHOULD|MAY)"
    r"(?:; (?P<checks>[a-z, ]+))?\) (?P<text>.*?)(?=^- \*\*|^\S|\Z)",
    re.M | re.S,
)
_DECISION = re.compile(r"^\*\*(?P<id>D-[A-Z]+-\d+) ", re.M)


@dataclass(frozen=True, slots=True)
class Requirement:
    id: str
    level: str
    #: "validate", "xsd", "dtd": the checks that enforce it (specs/README.md).
    checks: frozenset[str]
    text: str
    document: str

    @property
    def mandatory(self) -> bool:
        """MUST and MUST NOT; the validator reports them as errors, SHOULDs as warnings."""
        return self.level.startswith("MUST")


def specs_dir() -> Path:
    for candidate in _CANDIDATES:
        if candidate.is_dir():
            return candidate
    raise FileNotFoundError("the specs/ documents are not installed with this copy of rcmlconf")


def requirements(directory: Path | None = None) -> dict[str, Requirement]:
    """Every requirement of every document, by ID."""
    found: dict[str, Requirement] = {}
    for path in sorted((directory or specs_dir()).glob("*.md")):
        for match in _BULLET.finditer(path.read_text(encoding="utf-8")):
            text = " ".join(match.group("text").split())
            checks = frozenset(c.strip() for c in (match.group("checks") or "").split(",") if c)
            requirement = Requirement(
                match.group("id"), match.group("level"), checks, text, path.name
            )
            if requirement.id in found:
                raise ValueError(f"{requirement.id} is defined twice")
            found[requirement.id] = requirement
    return found


def decisions(directory: Path | None = None) -> set[str]:
    """Every decision ID (D-...) of every document."""
    return {
        match.group("id")
        for path in sorted((directory or specs_dir()).glob("*.md"))
        for match in _DECISION.finditer(path.read_text(encoding="utf-8"))
    }
