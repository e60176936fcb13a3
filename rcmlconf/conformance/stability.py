"""--verify N: which cases gave different verdicts across their N runs.

A case is stable when every run of it gave the same verdict. It is unstable otherwise, as in
web-platform-tests' `--verify`. A stable failure is a failure, not an instability.
The judgement counts verdicts only. Reasons differ from run to run and are not compared.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable, Mapping
from dataclasses import dataclass

from rcmlconf.conformance.verdicts import Result, Verdict

#: The JUnit failure type and the word the reports use.
UNSTABLE = "unstable"


@dataclass(frozen=True, slots=True)
class Unstable:
    """A case whose runs gave more than one verdict."""

    #: The case's ID.
    case: str
    #: Each verdict it got and how many runs got it, the most frequent first.
    verdicts: tuple[tuple[Verdict, int], ...]

    def counted(self) -> str:
        """The verdicts, such as `9 pass, 1 inconclusive`."""
        return ", ".join(f"{n} {verdict.value}" for verdict, n in self.verdicts)

    def __str__(self) -> str:
        return f"{UNSTABLE}: {self.counted()}"

    def counts(self) -> Mapping[str, int]:
        """The verdicts by name, as the JSON report has them."""
        return {verdict.value: n for verdict, n in self.verdicts}


def unstable(results: Iterable[Result]) -> list[Unstable]:
    """The unstable cases among `results`, in the order their cases first come."""
    found: dict[str, Counter[Verdict]] = {}
    for result in results:
        found.setdefault(result.case, Counter())[result.verdict] += 1
    order = list(Verdict)
    return [
        Unstable(case, tuple(sorted(got.items(), key=lambda v: (-v[1], order.index(v[0])))))
        for case, got in found.items()
        if len(got) > 1
    ]
