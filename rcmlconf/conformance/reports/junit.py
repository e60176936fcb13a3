"""--junit: JUnit XML as Jenkins, GitLab and GitHub's test reporters read it: one <testsuite> per
area (`rctp/msg`), one <testcase> per case and run, its classname the area and its name the
case's ID. A failure is <failure>, an error <error>; not applicable and inconclusive are
<skipped> with the verdict in the message (JUnit has no such verdicts). A known failure of the
baseline stays a <failure>: the report says what happened, the exit code what is new."""

from __future__ import annotations

import datetime
from collections.abc import Mapping, Sequence
from itertools import groupby

from lxml import etree

from rcmlconf.conformance.registry import Case
from rcmlconf.conformance.reports.summary import shown_exchange
from rcmlconf.conformance.verdicts import Result, Verdict


def to_junit(results: Sequence[Result], cases: Mapping[str, Case], started: float) -> bytes:
    stamp = datetime.datetime.fromtimestamp(started, datetime.UTC).strftime("%Y-%m-%dT%H:%M:%S")
    root = etree.Element("testsuites", name="rcmlconf run")
    _totals(root, results)

    def area(result: Result) -> str:
        return cases[result.case].area

    for name, group in groupby(sorted(results, key=area), key=area):
        members = list(group)
        suite = etree.SubElement(root, "testsuite", name=name, timestamp=stamp)
        _totals(suite, members)
        for result in members:
            _case(suite, result, cases[result.case])
    return bytes(etree.tostring(root, xml_declaration=True, encoding="UTF-8", pretty_print=True))


def _totals(element: etree._Element, results: Sequence[Result]) -> None:
    element.set("tests", str(len(results)))
    element.set("failures", str(sum(r.verdict is Verdict.FAIL for r in results)))
    element.set("errors", str(sum(r.verdict is Verdict.ERROR for r in results)))
    skipped = (Verdict.NOT_APPLICABLE, Verdict.INCONCLUSIVE)
    element.set("skipped", str(sum(r.verdict in skipped for r in results)))
    element.set("time", f"{sum(r.duration for r in results):.3f}")


def _case(suite: etree._Element, result: Result, case: Case) -> None:
    name = case.id if result.run == 1 else f"{case.id} (run {result.run})"
    element = etree.SubElement(
        suite, "testcase", name=name, classname=case.area, time=f"{result.duration:.3f}"
    )
    if result.verdict is Verdict.PASS:
        return
    tag = {Verdict.FAIL: "failure", Verdict.ERROR: "error"}.get(result.verdict, "skipped")
    message = result.reason if tag != "skipped" else f"{result.verdict.value}: {result.reason}"
    outcome = etree.SubElement(element, tag, message=_clean(message))
    if tag != "skipped":
        outcome.set("type", result.requirement or result.verdict.value)
        details = [f"requirements: {', '.join(case.requirements)}"]
        if result.expected:
            details.append(f"expected: {' | '.join(result.expected)}")
        if result.actual is not None:
            details.append(f"actual: {result.actual}")
        if result.known:
            details.append("known failure (baseline)")
        outcome.text = _clean("\n".join([*details, "", *shown_exchange(result)]))


def _clean(text: str) -> str:
    """XML 1.0 has no place for most control characters; the transcript may hold them."""
    return "".join(c if c in "\t\n" or ord(c) >= 0x20 else f"\\x{ord(c):02x}" for c in text)
