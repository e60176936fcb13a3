"""`rcmlconf run --html`: one self-contained page (nothing fetched), as a user opens it in a
browser: Debian's Chromium, headless, driven by Playwright. It renders, its filters work, and a
failing case shows its exchange and the plot of its datagrams."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from support.browser import chromium
from support.case_counts import MSG_CASES
from support.processes import run_command

#: The case sequence-skips fails (the reference server skips every other packet number).
FAILING = "rctp/stream/consecutive-sequence"
#: The results of the run: rctp/msg's and FAILING.
ALL = MSG_CASES + 1


@pytest.fixture(scope="module")
def report(tmp_path_factory: pytest.TempPathFactory) -> Path:
    page = tmp_path_factory.mktemp("html") / "report.html"
    args = ("--only", "rctp/msg/*", "--only", FAILING, "--fault", "sequence-skips")
    done = run_command("run", *args, "--html", str(page))
    assert done.returncode == 1, done.stderr
    return page


@pytest.fixture(scope="module")
def browser() -> Iterator[Any]:
    with chromium() as launched:
        yield launched


def test_the_page_is_one_file_that_names_nothing_to_fetch(report: Path) -> None:
    text = report.read_text()
    for outside in ("src=", "href=", "@import", "url("):
        assert outside not in text, outside
    assert "default-src 'none'" in text  # and the browser would fetch nothing anyway


def test_the_page_renders_filters_and_shows_a_failure_s_exchange(
    report: Path, browser: Any
) -> None:
    page = browser.new_page()
    fetched: list[str] = []
    page.on("request", lambda request: fetched.append(request.url))
    page.goto(report.as_uri())
    assert page.title() == "rcmlconf run: the embedded reference with sequence-skips"
    rows = page.locator("table.summary tr")
    assert rows.filter(has_text="rctp/msg").inner_text().split() == ["rctp/msg", str(MSG_CASES)]
    assert page.inner_text("#shown") == f"{ALL} of {ALL} results"

    page.select_option("#verdict", "fail")
    assert page.inner_text("#shown") == f"1 of {ALL} results"
    visible = page.locator("details.case:visible")
    assert visible.count() == 1
    failing = visible.first
    assert FAILING in failing.inner_text()

    page.select_option("#verdict", "")
    page.select_option("#area", "rctp/msg")
    assert page.inner_text("#shown") == f"{MSG_CASES} of {ALL} results"
    page.select_option("#area", "")
    page.fill("#requirement", "R-RCTP-41")
    assert page.locator("details.case:visible").count() == 1

    failing.locator("summary").click()
    assert failing.locator("dd", has_text="MUST").first.is_visible()  # the requirement's text
    directions = failing.locator("table.exchange tr td:nth-child(2)").all_inner_texts()
    assert {"sent", "received"} <= set(directions)
    plot = failing.locator("svg.intervals")
    assert plot.is_visible()
    assert plot.locator("polyline").count() == 1
    assert plot.locator("line.lost").count() > 0  # the numbers the server skipped
    assert fetched == [report.as_uri()]
    page.close()


def test_a_page_that_cannot_be_written_is_said_before_any_case_runs(tmp_path: Path) -> None:
    nowhere = tmp_path / "nowhere" / "report.html"
    done = run_command("run", "--only", "rctp/msg/*", "--html", str(nowhere))
    assert done.returncode == 2
    (line,) = done.stderr.splitlines()[-1:]
    assert "'--html'" in line
    assert "does not exist" in line
    same = str(tmp_path / "same")
    done = run_command("run", "--only", "rctp/msg/*", "--json", same, "--html", same)
    assert done.returncode == 2
    assert "--json and --html name the same file" in done.stderr
