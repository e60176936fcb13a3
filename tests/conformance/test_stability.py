"""--verify's judgement over hand-made results, and how each report shows an unstable case.

The reference has no random fault, so a real run gives no unstable case. These results
stand in for one: a case that passed twice and failed once.
"""

from __future__ import annotations

import io
from types import SimpleNamespace
from typing import Any

from lxml import etree
from support.report_schemas import assert_junit_valid, assert_run_report_valid

from rcmlconf.cli import run_suite
from rcmlconf.cli.console import Output
from rcmlconf.conformance.registry import all_cases
from rcmlconf.conformance.reports.html import to_html
from rcmlconf.conformance.reports.json_report import to_json
from rcmlconf.conformance.reports.junit import to_junit
from rcmlconf.conformance.reports.summary import run_status
from rcmlconf.conformance.stability import Unstable, unstable
from rcmlconf.conformance.verdicts import Result, Verdict

SPAN = (10.0, 12.5)


def shaky_runs() -> list[Result]:
    """Case 0: pass, pass, fail. Case 1: pass three times. Case 2: inconclusive three times."""
    first, second, third = list(all_cases())[:3]
    verdicts = {
        first: [Verdict.PASS, Verdict.PASS, Verdict.FAIL],
        second: [Verdict.PASS] * 3,
        third: [Verdict.INCONCLUSIVE] * 3,
    }
    return [
        Result(
            case=case,
            verdict=verdict,
            duration=0.1,
            reason="" if verdict is Verdict.PASS else f"{verdict.value} in run {run}",
            requirement="R-RCTP-9" if verdict is Verdict.FAIL else None,
            run=run,
            ended=11.0,
        )
        for run in (1, 2, 3)
        for case, runs in verdicts.items()
        for verdict in [runs[run - 1]]
    ]


def test_a_case_with_two_verdicts_is_unstable_with_its_counts() -> None:
    results = shaky_runs()
    found = unstable(results)
    assert found == [Unstable(results[0].case, ((Verdict.PASS, 2), (Verdict.FAIL, 1)))]
    assert str(found[0]) == "unstable: 2 pass, 1 fail"
    assert dict(found[0].counts()) == {"pass": 2, "fail": 1}


def test_same_verdicts_in_every_run_are_stable_even_when_not_a_pass() -> None:
    results = [r for r in shaky_runs() if r.case != shaky_runs()[0].case]
    assert unstable(results) == []
    assert unstable([]) == []


def test_ties_keep_the_verdicts_order() -> None:
    case = next(iter(all_cases()))
    results = [
        Result(case=case, verdict=v, duration=0.0, run=n)
        for n, v in enumerate([Verdict.INCONCLUSIVE, Verdict.PASS], 1)
    ]
    assert str(unstable(results)[0]) == "unstable: 1 pass, 1 inconclusive"


def test_an_unstable_case_fails_the_run_unless_an_error_says_more() -> None:
    passes = [r for r in shaky_runs() if r.verdict is Verdict.PASS]
    shaky = [Unstable(passes[0].case, ((Verdict.PASS, 9), (Verdict.INCONCLUSIVE, 1)))]
    assert run_status(passes, strict=False) == (0, "")
    assert run_status(passes, strict=False, unstable=shaky) == (1, "--verify: 1 case unstable")
    errors = [*passes, Result(case=passes[0].case, verdict=Verdict.ERROR, duration=0.0)]
    assert run_status(errors, strict=False, unstable=shaky)[0] == 2


def test_junit_has_a_failure_of_type_unstable_for_the_case() -> None:
    results = shaky_runs()
    written = to_junit(results, all_cases(), *SPAN, unstable(results))
    assert_junit_valid(written)
    document = etree.fromstring(written)
    assert (document.get("tests"), document.get("failures")) == ("10", "2")
    cases = document.findall(".//testcase")
    verified = [c for c in cases if c.get("name") == f"{results[0].case} (verify)"]
    assert len(verified) == 1
    failure = verified[0].find("failure")
    assert failure is not None
    assert failure.get("type") == "unstable"
    assert failure.get("message") == "unstable: 2 pass, 1 fail"
    assert (failure.text or "").splitlines() == [
        "run 1: pass",
        "run 2: pass",
        "run 3: fail: fail in run 3",
    ]


def report(results: list[Result], verify: int | None) -> dict[str, Any]:
    settings = {"seed": 0, "repeat": 3, "verify": verify, "timeout_scale": 1.0, "impair": None}
    found = unstable(results) if verify is not None else None
    return to_json(results, all_cases(), "the target", settings, SPAN, found)


def test_json_lists_the_unstable_case_and_validates_against_the_schema() -> None:
    results = shaky_runs()
    document = report(results, 3)
    assert_run_report_valid(document)
    assert document["version"] == 2
    assert document["unstable"] == [{"case": results[0].case, "verdicts": {"pass": 2, "fail": 1}}]
    assert_run_report_valid(report(results[1:2], 3))  # none unstable: []
    assert "unstable" not in report(results, None)


def test_html_lists_the_unstable_case_and_marks_its_results() -> None:
    results = shaky_runs()
    page = to_html(report(results, 3), {})
    assert "1 unstable (--verify 3)" in page
    assert page.count("unstable: 2 pass, 1 fail") == 1 + 3  # the list, and each of its runs
    stable = to_html(report(results[1:2], 3), {})
    assert "every case gave the same verdict in each of its 3 runs" in stable
    assert "unstable" not in to_html(report(results, None), {})


def test_the_text_report_names_the_case_its_verdicts_and_the_odd_run() -> None:
    results = shaky_runs()
    out, err = io.StringIO(), io.StringIO()
    target: Any = SimpleNamespace(name="the target")
    run_suite._report(Output(out, err), results, all_cases(), target, unstable(results))
    shown = out.getvalue().splitlines()
    at = shown.index(f"UNSTABLE {results[0].case}  unstable: 2 pass, 1 fail")
    assert shown[at + 1].split() == ["run", "3", "fail:", "fail", "in", "run", "3"]
    assert err.getvalue().splitlines()[-1].endswith("; 1 unstable")
