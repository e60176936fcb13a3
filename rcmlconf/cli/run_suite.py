"""`rcmlconf run` once its options are read (`rcmlconf.cli.run` declares them): each option and
file checked, the targets reached once, the cases run, and the reports written."""

from __future__ import annotations

import asyncio
import contextlib
import json
import sys
import time
from collections import Counter
from collections.abc import AsyncIterator, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any, NamedTuple

import click

from rcmlconf.cli.cases import chosen_cases, list_cases
from rcmlconf.cli.console import Output
from rcmlconf.cli.hosts import Address
from rcmlconf.cli.run_listen import (
    ClientTarget,
    LocalTarget,
    client_target,
    listen_command,
    local_target,
)
from rcmlconf.cli.run_options import (
    check_reports,
    loaded,
    robot_file,
    warn_unknown,
)
from rcmlconf.cli.run_progress import log_progress
from rcmlconf.cli.run_target import (
    CONNECT_WAIT,
    described,
    fetched_robot,
    reach,
    robot_problem,
    server_problem,
)
from rcmlconf.conformance.files import shown
from rcmlconf.conformance.giveup import NOT_RUN
from rcmlconf.conformance.ics import EVERYTHING, Ics, load_ics
from rcmlconf.conformance.probes.clients import HARNESS_RCML
from rcmlconf.conformance.registry import Case, all_cases
from rcmlconf.conformance.reports.baseline import load_baseline, mark_known
from rcmlconf.conformance.reports.html import to_html
from rcmlconf.conformance.reports.json_report import to_json
from rcmlconf.conformance.reports.junit import to_junit
from rcmlconf.conformance.reports.summary import counts, explain, new_failures, run_status
from rcmlconf.conformance.roles import Role
from rcmlconf.conformance.runner import (
    PARTLY,
    RunOptions,
    run_cases,
    under_test,
)
from rcmlconf.conformance.targets import Target, embedded_reference, quiet_reference_logs
from rcmlconf.conformance.verdicts import Result, Verdict
from rcmlconf.impair.spec import parse_impairment
from rcmlconf.rcml.model import RcmlDocument
from rcmlconf.reference.faults import Fault, describe, faults_named
from rcmlconf.rsp.model import RobotModel
from rcmlconf.validate.validator import load_robot, load_robot_model
from rcmlconf.wording import plural

_STYLE = {
    Verdict.PASS: "green",
    Verdict.FAIL: "bold red",
    Verdict.INCONCLUSIVE: "yellow",
    Verdict.NOT_APPLICABLE: "dim",
    Verdict.ERROR: "magenta",
}


def run_suite(
    target: Address | None,
    rcml: Path | None,
    site: str | None,
    rsp_target: Address | None,
    model: Path | None,
    ics: Path | None,
    role: str,
    listen: Address | None,
    client_command: str | None,
    connect_timeout: float,
    list_only: bool,
    strict: bool,
    only: tuple[str, ...],
    skip: tuple[str, ...],
    repeat: int,
    timeout_scale: float,
    session_wait: float,
    seed: int,
    impair: str | None,
    concurrency: int,
    junit: Path | None,
    json_file: Path | None,
    html_file: Path | None,
    baseline: Path | None,
    capture: Path | None,
    faults: tuple[str, ...],
    verbose: bool,
) -> None:
    """The run `rcmlconf run`'s help describes; its options by name."""
    output = Output()
    declared = loaded("--ics", load_ics, ics) if ics is not None else EVERYTHING
    known = loaded("--baseline", load_baseline, baseline) if baseline is not None else frozenset()
    impairment = loaded("--impair", parse_impairment, impair) if impair is not None else None
    _check_roles(role, target, rcml, site, rsp_target, model, listen, faults)
    command = listen_command(client_command, listen)
    robot = robot_file("--rcml", load_robot, rcml) if rcml is not None else None
    played = robot_file("--model", load_robot_model, model) if model is not None else None
    if not list_only:
        check_reports({"--junit": junit, "--json": json_file, "--html": html_file}, capture)
    registry = all_cases()
    chosen = chosen_cases(registry.values(), only, skip)
    if list_only:
        roles = _roles(role, target, rsp_target, listen)
        list_cases(output, [c for c in chosen if roles is None or c.role in roles])
        return
    if baseline is not None:
        warn_unknown(output, baseline, known, registry)
    options = RunOptions(
        timeout_scale=timeout_scale,
        seed=seed,
        concurrency=concurrency,
        repeat=repeat,
        impair=impairment,
        capture=capture,
        session_wait=session_wait,
        connect_timeout=connect_timeout,
    )
    if capture is not None:
        try:
            capture.mkdir(parents=True, exist_ok=True)
        except OSError as error:
            raise click.BadParameter(
                f"{shown(capture)} cannot be made: {error.strerror or error}",
                param_hint="'--capture'",
            ) from None
    external: Target | ClientTarget | LocalTarget | None = None
    if target is not None or rsp_target is not None:
        if target is not None:
            wait = CONNECT_WAIT * timeout_scale
            reach(output, "--target", target, "RCTP over TCP", server_problem(target, wait))
            robot = robot or fetched_robot(output, target, wait)
        if rsp_target is not None:
            reach(output, "--rsp-target", rsp_target, "RSP over UDP", robot_problem(rsp_target))
        external = _external(output, target, robot, site, rsp_target, played, declared)
    elif listen is not None and played is not None and role == "local":
        external = LocalTarget(listen, played, declared, command)
    elif listen is not None:
        served = rcml if robot is not None and rcml is not None else HARNESS_RCML
        robot = robot or load_robot(served)
        external = ClientTarget(listen, robot, served, declared.features, command)
    if external is None:
        quiet_reference_logs()
    started = time.time()
    try:
        tested, results = asyncio.run(
            _run(external, declared, faults_named(faults), chosen, options, output, verbose)
        )
    except OSError as error:
        why = error.strerror or str(error)
        if listen is not None:
            output.problem("run", f"cannot listen on --listen {described(listen)}: {why}")
        else:
            output.problem("run", f"cannot start the embedded reference: {why}")
        sys.exit(2)
    span = (started, time.time())
    results = mark_known(results, known)
    settings = {"seed": seed, "repeat": repeat, "timeout_scale": timeout_scale, "impair": impair}
    files = _Reports(junit, json_file, html_file)
    _write_reports(output, results, registry, tested, settings, span, files)
    _report(output, results, registry, tested)
    status, why = run_status(results, strict)
    if why:
        output.problem("run", why)
    sys.exit(status)


async def _run(
    external: Target | ClientTarget | LocalTarget | None,
    declared: Ics,
    faults: frozenset[Fault],
    chosen: Sequence[Case],
    options: RunOptions,
    output: Output,
    verbose: bool,
) -> tuple[Target, list[Result]]:
    async with _target(external, declared, faults, output) as target:
        cases = [c for c in chosen if under_test(c, target)]
        if len(cases) < len(chosen):
            output.notice(_left_out([c for c in chosen if c not in cases], target.name))
        total = len(cases) * options.repeat
        with output.progress(total, "cases") as step:
            async with log_progress(output, total) as logged:

                def done(result: Result) -> None:
                    step(f"{result.verdict.value}: {result.case}")
                    logged(result)
                    if verbose or result.verdict in (Verdict.FAIL, Verdict.ERROR):
                        output.live(
                            [
                                (f"{result.verdict.value:>14} ", _STYLE[result.verdict]),
                                (result.case, "bold"),
                                (f"  {result.reason}", "dim"),
                            ]
                        )
                    if verbose and result.used:
                        output.live([(f"{'':>14} used {', '.join(result.used)}", "dim")])

                results = await run_cases(cases, target, options, done)
        return target, results


@contextlib.asynccontextmanager
async def _target(
    external: Target | ClientTarget | LocalTarget | None,
    declared: Ics,
    faults: frozenset[Fault],
    output: Output,
) -> AsyncIterator[Target]:
    if isinstance(external, LocalTarget):
        async with local_target(external, output) as target:
            yield target
        return
    if isinstance(external, ClientTarget):
        async with client_target(external, output) as target:
            yield target
        return
    if external is not None:
        yield external
        return
    async with embedded_reference(declared.features, faults) as reference:
        if faults:
            reference = replace(reference, name=f"the embedded reference with {describe(faults)}")
        yield reference


#: How a run tests each role: what to give `run` for it.
_HOW = {
    Role.SERVER: "an RCTP server: --target",
    Role.ROBOT: "an RSP robot: --rsp-target",
    Role.CLIENT: "an RCTP client: --role client --listen",
    Role.LOCAL: "an RSP local system: --role local --listen",
}


def _left_out(cases: Sequence[Case], tested: str) -> str:
    """Which of the cases chosen test a role `tested` does not play, and how to test it."""
    roles = Counter(case.role for case in cases)
    each = "; ".join(f"{plural(n, 'case')} of {_HOW[role]}" for role, n in roles.items())
    return f"left out, as {tested} does not play their role: {each}"


def _external(
    output: Output,
    target: Address | None,
    robot: RcmlDocument | None,
    site: str | None,
    rsp_target: Address | None,
    rsp_model: RobotModel | None,
    declared: Ics,
) -> Target:
    names = [described(address) for address in (target, rsp_target) if address is not None]
    return Target(
        server=target,
        robot=robot,
        site_path=site or (robot.site.path if robot is not None else "/"),
        rsp=(rsp_target,) if rsp_target is not None else (),
        rsp_model=rsp_model,
        rsp_psk=declared.psk,
        features=declared.features,
        name=" and ".join(names),
    )


def _check_roles(
    role: str,
    target: Address | None,
    rcml: Path | None,
    site: str | None,
    rsp_target: Address | None,
    model: Path | None,
    listen: Address | None,
    faults: tuple[str, ...],
) -> None:
    """The options that go together, for the role tested."""
    if rsp_target is not None and model is None:
        raise click.UsageError("--rsp-target needs the robot's --model")
    if role == "client":
        if listen is None:
            raise click.UsageError("--role client needs --listen PORT for the client to connect")
        if target is not None or rsp_target is not None:
            raise click.UsageError("--role client tests a client: leave out --target/--rsp-target")
    elif role == "local":
        if listen is None or model is None:
            raise click.UsageError("--role local needs --listen PORT and the --model to play")
        if target is not None or rsp_target is not None:
            raise click.UsageError("--role local tests a local system: leave out the targets")
    elif listen is not None:
        raise click.UsageError("--listen is for --role client and --role local")
    if faults and (target is not None or rsp_target is not None or listen is not None):
        raise click.UsageError("--fault is for the embedded reference: leave out the targets")
    if (rcml is not None or site is not None) and target is None:
        raise click.UsageError("--rcml and --site describe --target: give --target too")
    if model is not None and rsp_target is None and role != "local":
        raise click.UsageError(
            "--model describes --rsp-target, or the robot --role local plays: give one of them"
        )


class _Reports(NamedTuple):
    """The files the run's reports go to (--junit, --json, --html)."""

    junit: Path | None
    json: Path | None
    html: Path | None


def _write_reports(
    output: Output,
    results: list[Result],
    registry: dict[str, Case],
    target: Target,
    settings: dict[str, Any],
    span: tuple[float, float],
    files: _Reports,
) -> None:
    """`span`: when the run started and ended (time.time())."""
    try:
        if files.junit is not None:
            files.junit.write_bytes(to_junit(results, registry, *span))
        if files.json is None and files.html is None:
            return
        report = to_json(results, registry, target.name, settings, span)
        if files.json is not None:
            files.json.write_text(json.dumps(report, indent=2, ensure_ascii=False) + "\n")
        if files.html is not None:
            from rcmlconf.specs import requirements

            texts = {k: f"{r.level}: {r.text}" for k, r in requirements().items()}
            files.html.write_text(to_html(report, texts), encoding="utf-8")
    except OSError as error:
        output.problem("run", f"cannot write the report: {error}")
        sys.exit(2)


def _report(
    output: Output, results: list[Result], registry: dict[str, Case], target: Target
) -> None:
    from rcmlconf.specs import requirements

    texts = requirements()
    for result in results:
        if result.verdict not in (Verdict.FAIL, Verdict.ERROR):
            continue
        label = f"{result.verdict.value.upper()}{' (known)' if result.known else ''}"
        output.out.line([(label, _STYLE[result.verdict]), (f" {result.case}", "bold")])
        for name, text in explain(result, registry[result.case], texts):
            output.out.line([(f"  {name:>11}  ", "dim"), (text, "")])
    _table(output, results, registry)
    partly = sum(1 for r in results if r.verdict is Verdict.PASS and r.reason.startswith(PARTLY))
    if partly:
        output.notice(
            f"{partly} {'pass' if partly == 1 else 'passes'} checked only part of the"
            " requirement, as the target could not show the rest (run -v or --json says which"
            " part and why)"
        )
    skipped = [r for r in results if r.reason.startswith(NOT_RUN)]
    if skipped:  # GiveUp: the same reason for each
        not_run = f"{plural(len(skipped), 'case')} {skipped[0].reason}"
        output.notice(f"gave up on {target.name}: {not_run}")
    found = counts(results)
    fresh = new_failures(results)
    line = ", ".join(f"{n} {v.value}" for v, n in found.items() if n)
    output.summary(f"{target.name}: {len(results)} results: {line}", not fresh)


def _table(output: Output, results: list[Result], registry: dict[str, Case]) -> None:
    """Verdicts by area: one row an area, one column a verdict."""
    areas: dict[str, list[Result]] = {}
    for result in results:
        areas.setdefault(registry[result.case].area, []).append(result)
    header = "".join(f"{v.value:>15}" for v in Verdict)
    output.err.line([(f"{'area':<16}{header}", "bold")])
    for area, members in sorted(areas.items()):
        found = counts(members)
        cells = [(f"{found[v] or '':>15}", _STYLE[v] if found[v] else "") for v in Verdict]
        output.err.line([(f"{area:<16}", ""), *cells])


def _roles(
    role: str, target: Address | None, rsp_target: Address | None, listen: Address | None
) -> set[Role] | None:
    """The roles a run with these options tests; None: every one (the embedded reference)."""
    if target is not None or rsp_target is not None:
        return {r for r, given in ((Role.SERVER, target), (Role.ROBOT, rsp_target)) if given}
    if listen is not None:
        return {Role.CLIENT if role == "client" else Role.LOCAL}
    return None
