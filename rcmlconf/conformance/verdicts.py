"""The five verdicts of a case, and the exceptions a case stops with to give one.

The verdicts are pass, fail, inconclusive, not applicable and error.
A case that returns passes.
`Failed` is the target's fault. It carries the requirement broken, every outcome the
requirement accepts, and what happened.
`Inconclusive` means the case could not tell. A precondition that another case checks did
not hold, or the impairment hid the answer.
`NotApplicable` means the target lacks an optional feature the case needs (ICS or model).
An error is the fault of the harness or of the network, such as a refused connection or a
bug. It is never the target's failure.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

from rcmlconf.conformance.transcript import Entry


class Verdict(enum.Enum):
    PASS = "pass"
    FAIL = "fail"
    INCONCLUSIVE = "inconclusive"
    NOT_APPLICABLE = "not applicable"
    ERROR = "error"


class CaseStop(Exception):
    """How a case ends with a verdict other than pass."""

    verdict: Verdict

    def __init__(self, reason: str) -> None:
        super().__init__(reason)
        self.reason = reason


class Failed(CaseStop):
    verdict = Verdict.FAIL

    def __init__(
        self, requirement: str, expected: tuple[str, ...] | str, actual: str, reason: str = ""
    ) -> None:
        expected = (expected,) if isinstance(expected, str) else expected
        super().__init__(reason or f"expected {' or '.join(expected)}; got {actual}")
        self.requirement = requirement
        self.expected = expected
        self.actual = actual


class Inconclusive(CaseStop):
    verdict = Verdict.INCONCLUSIVE


class NotApplicable(CaseStop):
    verdict = Verdict.NOT_APPLICABLE


class HarnessError(CaseStop):
    """The harness or the network failed; the target is not to blame."""

    verdict = Verdict.ERROR


@dataclass(frozen=True, slots=True, kw_only=True)
class Result:
    """One run of one case. Give every field by name."""

    #: The case's ID.
    case: str
    verdict: Verdict
    #: Seconds.
    duration: float
    #: Why, in a sentence. Empty for a pass.
    reason: str = ""
    #: For a failure: the requirement broken, what it accepts, and what happened.
    requirement: str | None = None
    expected: tuple[str, ...] = ()
    actual: str | None = None
    #: The exchange that led to the verdict, one line a message or event.
    exchange: tuple[str, ...] = ()
    #: Which of --repeat's runs it is, from 1.
    run: int = 1
    #: A failure that the baseline lists. It does not fail the run.
    known: bool = False
    #: The nodes and devices the case named (`Transcript.used`): what its checks could show.
    used: tuple[str, ...] = ()
    #: When the case ended (time.time()). With `duration`, it says when the case ran. The
    #: reports draw spans from it, as cases run side by side: an area's time is not the sum
    #: of its cases' times.
    ended: float = 0.0
    #: The exchange as data (`Transcript.entries`), for --json and --html.
    entries: tuple[Entry, ...] = ()
