"""Counts by verdict and the explanation of a failure, as plain data for the console to style."""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable, Mapping, Sequence

from rcmlconf.conformance.registry import Case
from rcmlconf.conformance.stability import Unstable
from rcmlconf.conformance.verdicts import Result, Verdict
from rcmlconf.specs import Requirement
from rcmlconf.wording import plural


def counts(results: Iterable[Result]) -> dict[Verdict, int]:
    """Results by verdict, every verdict present (0 for none); known failures count as fail."""
    found = Counter(r.verdict for r in results)
    return {verdict: found.get(verdict, 0) for verdict in Verdict}


def new_failures(results: Iterable[Result]) -> list[Result]:
    """Failures and errors the baseline does not list: what fails the run."""
    return [r for r in results if r.verdict in (Verdict.FAIL, Verdict.ERROR) and not r.known]


def explain(
    result: Result, case: Case, requirements: Mapping[str, Requirement]
) -> list[tuple[str, str]]:
    """A failure as (label, text) lines: the case, the requirement's text, every acceptable
    outcome, what happened, and the exchange that led there."""
    lines = [("case", f"{case.id} — {case.purpose}")]
    if result.requirement is not None:
        found = requirements.get(result.requirement)
        text = f"{found.level}: {found.text}" if found else "(not in specs/)"
        lines.append(("requirement", f"{result.requirement} {text}"))
    if result.expected:
        lines.append(("expected", " | ".join(result.expected)))
    if result.actual is not None:
        lines.append(("actual", result.actual))
    if result.reason and result.verdict is not Verdict.FAIL:
        lines.append(("why", result.reason))
    lines += [("exchange", line) for line in shown_exchange(result)]
    return lines


#: Lines of a failure's exchange a report shows; --json holds what the result kept.
SHOWN_EXCHANGE = 40


def shown_exchange(result: Result) -> list[str]:
    """The last SHOWN_EXCHANGE lines of the exchange, after a line saying where the rest is."""
    lines = list(result.exchange)
    if len(lines) <= SHOWN_EXCHANGE:
        return lines
    earlier = len(lines) - SHOWN_EXCHANGE
    return [f"... {earlier} lines before (--json has them)", *lines[-SHOWN_EXCHANGE:]]


def run_status(
    results: list[Result], strict: bool, unstable: Sequence[Unstable] = ()
) -> tuple[int, str]:
    """The run's exit status, and why where the table does not say it.

    It is 1 for a failure the baseline does not list, an `unstable` case (--verify), or with
    `strict` an inconclusive case. It is 2 for an error, or for a run in which no case passed or
    failed: it tested nothing, and must not pass a CI gate. An error outranks an unstable case:
    the harness could not do its job.
    """
    fresh = new_failures(results)
    if any(r.verdict is Verdict.FAIL for r in fresh):
        return 1, ""
    if fresh:
        return 2, ""
    decided = [r for r in results if r.verdict in (Verdict.PASS, Verdict.FAIL)]
    if results and not decided:
        found = Counter(r.verdict.value for r in results)
        shown = ", ".join(f"{n} {verdict}" for verdict, n in found.most_common())
        reason = Counter(r.reason for r in results if r.reason).most_common(1)
        first = f"; most often: {reason[0][0]}" if reason else ""
        return 2, f"no case passed or failed ({shown}): nothing was tested{first}"
    if unstable:
        return 1, f"--verify: {plural(len(unstable), 'case')} unstable"
    unsure = [r for r in results if r.verdict is Verdict.INCONCLUSIVE and not r.known]
    if strict and unsure:
        return 1, f"--strict: {plural(len(unsure), 'case')} inconclusive"
    return 0, ""
