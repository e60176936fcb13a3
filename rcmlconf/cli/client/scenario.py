"""`scenario`: D-RCTP-31's conformance scenario of a client, on one case URL or on each URL of a
harness's case list, one line a run."""

from __future__ import annotations

import asyncio
import contextlib
import sys
from collections.abc import Coroutine
from typing import Any, NoReturn

import click

from rcmlconf.cli.client.inputs import check_http_url, check_url, shown
from rcmlconf.cli.client.running import Options
from rcmlconf.cli.interrupts import Interrupts
from rcmlconf.errors import ValueTextError
from rcmlconf.rcml.model import RcmlDocument
from rcmlconf.rcml.url import RctpUrl
from rcmlconf.reference.client.fetching import Deadline, Unfetched, fetch
from rcmlconf.reference.client.files import NoModel, is_http_url, load_rcml
from rcmlconf.reference.client.scenario import ScenarioResult, run_scenario

#: The most of a case list the client takes: URLs, and bytes.
MAX_CASES = 10_000
MAX_LIST_BYTES = 1024 * 1024


def run_cases(options: Options) -> NoReturn:
    """Check URL, load --rcml and the case list, then run the scenario on each case in turn.
    Exit 0 once every run ran, 1 when Ctrl-C cut them short, 2 for URL, the list or --rcml."""
    listed = is_http_url(options.url)
    try:
        cases = [] if listed else [check_url(options.url)]
        if listed:
            check_http_url(options.url)
    except ValueTextError as exc:
        lists = "" if listed else " (nor the http URL of a case list)"
        raise click.BadParameter(f"{exc}{lists}", param_hint="'URL'") from None
    within = Deadline(options.timeout)
    try:
        model = None if options.rcml is None else load_rcml(options.rcml, within)
        cases = cases or _listed(options.url, within)
    except (NoModel, Unfetched, ValueTextError) as exc:
        options.output.problem("client", str(exc))
        sys.exit(2)
    sys.exit(asyncio.run(_run(options, cases, model)))


def _listed(url: str, within: Deadline) -> list[RctpUrl]:
    """The case URLs of a harness's list: text/plain, one a line (D-RCTP-31)."""
    try:
        text = fetch(url, within, MAX_LIST_BYTES).decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ValueTextError(f"{shown(url)} is not UTF-8 text (at offset {exc.start})") from None
    lines = [(n, line.strip()) for n, line in enumerate(text.splitlines(), 1) if line.strip()]
    if not lines:
        raise ValueTextError(f"{shown(url)} lists no case URL")
    if len(lines) > MAX_CASES:
        raise ValueTextError(
            f"{shown(url)} lists {len(lines):,} case URLs; the client runs at most {MAX_CASES:,}"
        )
    cases: list[RctpUrl] = []
    for number, line in lines:
        try:
            cases.append(check_url(line))
        except ValueTextError as exc:
            raise ValueTextError(f"{shown(url)}, line {number}: {exc}") from None
    return cases


async def _run(options: Options, cases: list[RctpUrl], model: RcmlDocument | None) -> int:
    with Interrupts() as interrupts:
        for case in cases:
            run = run_scenario(case, model=model, timeout=options.timeout)
            result = await _unless_interrupted(interrupts, run)
            if result is None:
                options.output.problem("client", f"{case}: interrupted")
                return 1
            _show(options, result)
    return 0


async def _unless_interrupted(
    interrupts: Interrupts, run: Coroutine[Any, Any, ScenarioResult]
) -> ScenarioResult | None:
    """The run's result; None at Ctrl-C, once the run's session has said BYE."""
    task = asyncio.ensure_future(run)
    signalled = asyncio.ensure_future(interrupts.wait())
    await asyncio.wait((task, signalled), return_when=asyncio.FIRST_COMPLETED)
    signalled.cancel()
    if task.done():
        return task.result()
    task.cancel()
    with contextlib.suppress(asyncio.CancelledError):
        await task
    return None


def _show(options: Options, result: ScenarioResult) -> None:
    if options.json:
        options.output.json_line(
            {
                "url": result.url,
                "ending": result.ending.name.lower(),
                "detail": result.detail,
                "refused": list(result.refused),
            }
        )
    else:
        options.output.live([(str(result), "")])
