"""Counts by verdict and the explanation of a failure, as plain data for the console to style."""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable, Mapping

from rcmlconf.conformance.registry import Case
from rcmlconf.conformance.verdicts import Result, Verdict
from rcmlconf.specs import Requirement


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
