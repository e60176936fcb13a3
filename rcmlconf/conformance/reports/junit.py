"""--junit: JUnit XML as Jenkins, GitLab and GitHub's test reporters read it: one <testsuite> per
area (`rctp/msg`), one <testcase> per case and run, its classname the area and its name the
case's ID. A failure is <failure>, an error <error>; not applicable and inconclusive are
<skipped> with the verdict and the reason as its text (JUnit has no such verdicts). A known
failure of the baseline stays a <failure>: the report says what happened, the exit code what is
new.
With --verify, each unstable case adds a <testcase> named `ID (verify)`, whose <failure> has
the type `unstable` and the verdicts its runs got as its message.

Valid against the schema Jenkins' JUnit reader checks (tests/support/junit.xsd says its rules):
<testsuites> takes no `skipped` count and <skipped> no attributes. Cases run side by side, so a
time is the wall time they took, not the sum of their durations: the run's for <testsuites>, the
span from an area's first case's start to its last one's end for its <testsuite>."""

from __future__ import annotations

import datetime
from collections.abc import Mapping, Sequence
from itertools import groupby

from lxml import etree

from rcmlconf.conformance.registry import Case
from rcmlconf.conformance.reports.summary import shown_exchange
from rcmlconf.conformance.stability import UNSTABLE, Unstable
from rcmlconf.conformance.verdicts import Result, Verdict


def to_junit(
    results: Sequence[Result],
    cases: Mapping[str, Case],
    started: float,
    ended: float,
    unstable: Sequence[Unstable] = (),
) -> bytes:
    """`started` and `ended`: the run's wall-clock times (time.time()). `unstable`: the cases
    --verify found unstable."""
    root = etree.Element("testsuites", name="rcmlconf run")
    _counts(root, results, len(unstable))
    root.set("time", _seconds(ended - started))

    def area(result: Result) -> str:
        return cases[result.case].area

    for name, group in groupby(sorted(results, key=area), key=area):
        members = list(group)
        first = min((r.ended - r.duration for r in members), default=started)
        suite = etree.SubElement(root, "testsuite", name=name, timestamp=_stamp(first))
        shaky = [u for u in unstable if cases[u.case].area == name]
        _counts(suite, members, len(shaky))
        skipped = (Verdict.NOT_APPLICABLE, Verdict.INCONCLUSIVE)
        suite.set("skipped", str(sum(r.verdict in skipped for r in members)))
        suite.set("time", _seconds(max(r.ended for r in members) - first))
        for result in members:
            _case(suite, result, cases[result.case])
        for found in shaky:
            _unstable(suite, found, [r for r in members if r.case == found.case])
    return bytes(etree.tostring(root, xml_declaration=True, encoding="UTF-8", pretty_print=True))


def _counts(element: etree._Element, results: Sequence[Result], unstable: int) -> None:
    """`unstable`: the testcases of unstable cases, one failure each."""
    element.set("tests", str(len(results) + unstable))
    failures = sum(r.verdict is Verdict.FAIL for r in results) + unstable
    element.set("failures", str(failures))
    element.set("errors", str(sum(r.verdict is Verdict.ERROR for r in results)))


def _seconds(seconds: float) -> str:
    return f"{max(seconds, 0.0):.3f}"


def _stamp(at: float) -> str:
    return datetime.datetime.fromtimestamp(at, datetime.UTC).strftime("%Y-%m-%dT%H:%M:%S")


def _case(suite: etree._Element, result: Result, case: Case) -> None:
    name = case.id if result.run == 1 else f"{case.id} (run {result.run})"
    element = etree.SubElement(
        suite, "testcase", name=name, classname=case.area, time=f"{result.duration:.3f}"
    )
    if result.verdict is Verdict.PASS:
        return
    tag = {Verdict.FAIL: "failure", Verdict.ERROR: "error"}.get(result.verdict)
    if tag is None:
        skipped = etree.SubElement(element, "skipped")
        skipped.text = _clean(f"{result.verdict.value}: {result.reason}")
        return
    outcome = etree.SubElement(element, tag, message=_clean(result.reason))
    outcome.set("type", result.requirement or result.verdict.value)
    details = [f"requirements: {', '.join(case.requirements)}"]
    if result.expected:
        details.append(f"expected: {' | '.join(result.expected)}")
    if result.actual is not None:
        details.append(f"actual: {result.actual}")
    if result.known:
        details.append("known failure (baseline)")
    outcome.text = _clean("\n".join([*details, "", *shown_exchange(result)]))


def _unstable(suite: etree._Element, found: Unstable, runs: Sequence[Result]) -> None:
    """The testcase of an unstable case: its time is its runs', its text each run's verdict."""
    area = suite.get("name", "")
    took = sum(r.duration for r in runs)
    element = etree.SubElement(
        suite, "testcase", name=f"{found.case} (verify)", classname=area, time=f"{took:.3f}"
    )
    outcome = etree.SubElement(element, "failure", message=str(found), type=UNSTABLE)
    lines = [f"run {r.run}: {r.verdict.value}{f': {r.reason}' if r.reason else ''}" for r in runs]
    outcome.text = _clean("\n".join(lines))


def _clean(text: str) -> str:
    """XML 1.0 has no place for most control characters; the transcript may hold them."""
    return "".join(c if c in "\t\n" or ord(c) >= 0x20 else f"\\x{ord(c):02x}" for c in text)
