"""Which cases check which requirement (`rcmlconf cases --matrix`): every MUST and SHOULD of
specs/ with the cases naming it, or the validator's checks where a file rule is enforced by
`rcmlconf validate` rather than at run time, or why no black-box case can check it where specs/
tags it `unobservable` (specs/README.md, "Reading a requirement")."""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass

from rcmlconf.conformance.registry import Case
from rcmlconf.specs import Requirement

#: The levels a matrix lists: MAY binds nobody.
LEVELS = ("MUST", "MUST NOT", "SHOULD", "SHOULD NOT")
#: The checks of a requirement that `rcmlconf validate` and the schemas make.
FILE_CHECKS = frozenset({"validate", "xsd", "dtd"})
#: The tag of a requirement no black-box case can check; its bullet says why after the marker.
UNOBSERVABLE = "unobservable"
_BECAUSE = "Unobservable:"


@dataclass(frozen=True, slots=True)
class Row:
    requirement: Requirement
    cases: tuple[str, ...]

    @property
    def by_validator(self) -> bool:
        return bool(self.requirement.checks & FILE_CHECKS)

    @property
    def covered(self) -> bool:
        return bool(self.cases) or self.by_validator

    @property
    def unobservable(self) -> str | None:
        """Why no case can check the requirement (specs/ tags it so), or None."""
        if UNOBSERVABLE not in self.requirement.checks:
            return None
        return self.requirement.text.partition(_BECAUSE)[2].strip() or "specs/ gives no reason"

    @property
    def missing(self) -> bool:
        """No case covers it though one could: what `cases --matrix --strict` counts."""
        return not self.covered and self.unobservable is None


def matrix(cases: Iterable[Case], requirements: Mapping[str, Requirement]) -> list[Row]:
    """A row for every MUST/SHOULD requirement, in document then number order."""
    covering: dict[str, list[str]] = {}
    for case in cases:
        for requirement in case.requirements:
            covering.setdefault(requirement, []).append(case.id)
    rows = [
        Row(r, tuple(covering.get(r.id, ()))) for r in requirements.values() if r.level in LEVELS
    ]
    return sorted(rows, key=lambda row: (row.requirement.document, _number(row.requirement.id)))


def unknown_requirements(
    cases: Iterable[Case], requirements: Mapping[str, Requirement]
) -> dict[str, list[str]]:
    """Requirement IDs cases name that specs/ does not define, with the cases naming them."""
    found: dict[str, list[str]] = {}
    for case in cases:
        for requirement in case.requirements:
            if requirement not in requirements:
                found.setdefault(requirement, []).append(case.id)
    return found


def _number(requirement_id: str) -> int:
    return int(requirement_id.rsplit("-", 1)[1])
