"""`rcmlconf run` once click has read its options into a `RunSettings`.

`rcmlconf.cli.run` declares the options. This module checks each option and file, reaches the
targets once, runs the cases and writes the reports. Every check comes before any case runs.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import sys
import time
from collections import Counter
from collections.abc import AsyncIterator, Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, NoReturn, TypeVar

import click

from rcmlconf.cli.cases import chosen_cases, list_cases
from rcmlconf.cli.console import Output
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
from rcmlconf.conformance.command import Command
from rcmlconf.conformance.files import shown
from rcmlconf.conformance.giveup import NOT_RUN
from rcmlconf.conformance.ics import EVERYTHING, Ics, load_ics
from rcmlconf.conformance.probes.clients import HARNESS_RCML
from rcmlconf.conformance.probes.inbound import arrival_clock
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
from rcmlconf.conformance.settings import ReportFiles, RunSettings, TargetSettings
from rcmlconf.conformance.stability import Unstable, unstable
from rcmlconf.conformance.targets import Target, embedded_reference, quiet_reference_logs
from rcmlconf.conformance.verdicts import Result, Verdict
from rcmlconf.impair.spec import Impairment, parse_impairment
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

#: What the run tests: a target it reached, or a client or local system it waits for.
#: None: the embedded reference.
External = Target | ClientTarget | LocalTarget | None

T = TypeVar("T")
V = TypeVar("V")


@dataclass(frozen=True, slots=True, kw_only=True)
class _Inputs:
    """What the options' files and specs hold, read and checked."""

    #: --ics, or an ICS that declares everything.
    declared: Ics
    #: The case IDs of --baseline.
    known: frozenset[str]
    impairment: Impairment | None
    command: Command | None
    #: The robot of --rcml.
    robot: RcmlDocument | None
    #: The robot model of --model.
    played: RobotModel | None


def run_suite(settings: RunSettings) -> None:
    """Run `rcmlconf run` as its help says, and exit with the run's status."""
    output = Output()
    inputs = _inputs(settings)
    registry = all_cases()
    chosen = chosen_cases(registry.values(), settings.only, settings.skip)
    if settings.list_only:
        roles = _roles(settings.tested)
        list_cases(output, [c for c in chosen if roles is None or c.role in roles])
        return
    if settings.baseline is not None:
        warn_unknown(output, settings.baseline, inputs.known, registry)
    _make_capture(settings.capture)
    external = _external(output, settings, inputs)
    target, results, span = _run_or_exit(output, settings, inputs, external, chosen)
    results = mark_known(results, inputs.known)
    shaky = unstable(results) if settings.verify is not None else None
    _write_reports(output, results, registry, target, settings, span, shaky)
    _report(output, results, registry, target, shaky)
    status, why = run_status(results, settings.strict, shaky or ())
    if why:
        output.problem("run", why)
    sys.exit(status)


def _inputs(settings: RunSettings) -> _Inputs:
    """Read and check what the options name. The order is the order of their errors."""
    tested = settings.tested
    declared = _given("--ics", load_ics, tested.ics, EVERYTHING)
    known = _given("--baseline", load_baseline, settings.baseline, frozenset[str]())
    impairment = _given("--impair", parse_impairment, settings.impair, None)
    _check_roles(tested)
    inputs = _Inputs(
        declared=declared,
        known=known,
        impairment=impairment,
        command=listen_command(tested.client_command, tested.listen),
        robot=_given("--rcml", load_robot, tested.rcml, None, robot_file),
        played=_given("--model", load_robot_model, tested.model, None, robot_file),
    )
    if not settings.list_only:
        check_reports(_report_options(settings.reports), settings.capture)
    return inputs


def _given(
    option: str,
    load: Callable[[V], T],
    value: V | None,
    default: T,
    read: Callable[[str, Callable[[V], T], V], T] = loaded,
) -> T:
    """`read(option, load, value)`: `loaded`, or `robot_file` for a robot's file. `default`
    when the option is not given."""
    return default if value is None else read(option, load, value)


def _report_options(files: ReportFiles) -> dict[str, Path | None]:
    """Each report option, with its file if given."""
    return {"--junit": files.junit, "--json": files.json, "--html": files.html}


def _make_capture(capture: Path | None) -> None:
    """Make the directory of --capture, or refuse the option."""
    if capture is None:
        return
    try:
        capture.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise click.BadParameter(
            f"{shown(capture)} cannot be made: {error.strerror or error}",
            param_hint="'--capture'",
        ) from None


def _external(output: Output, settings: RunSettings, inputs: _Inputs) -> External:
    """What the run tests. A target is reached once here, before any case runs."""
    tested = settings.tested
    robot = inputs.robot
    if tested.target is not None or tested.rsp_target is not None:
        if tested.target is not None:
            wait = CONNECT_WAIT * settings.timeout_scale
            problem = server_problem(tested.target, wait)
            reach(output, "--target", tested.target, "RCTP over TCP", problem)
            robot = robot or fetched_robot(output, tested.target, wait)
        if tested.rsp_target is not None:
            problem = robot_problem(tested.rsp_target)
            reach(output, "--rsp-target", tested.rsp_target, "RSP over UDP", problem)
        return _reached(tested, robot, inputs)
    if tested.listen is None:
        return None
    if inputs.played is not None and tested.role == "local":
        return LocalTarget(
            listen=tested.listen, model=inputs.played, ics=inputs.declared, command=inputs.command
        )
    served = tested.rcml if robot is not None and tested.rcml is not None else HARNESS_RCML
    return ClientTarget(
        listen=tested.listen,
        robot=robot or load_robot(served),
        rcml=served,
        features=inputs.declared.features,
        command=inputs.command,
    )


def _reached(tested: TargetSettings, robot: RcmlDocument | None, inputs: _Inputs) -> Target:
    """The --target and --rsp-target given, as one target."""
    addresses = (tested.target, tested.rsp_target)
    names = [described(address) for address in addresses if address is not None]
    return Target(
        server=tested.target,
        robot=robot,
        site_path=tested.site or (robot.site.path if robot is not None else "/"),
        rsp=(tested.rsp_target,) if tested.rsp_target is not None else (),
        rsp_model=inputs.played,
        rsp_psk=inputs.declared.psk,
        features=inputs.declared.features,
        name=" and ".join(names),
    )


def _run_or_exit(
    output: Output,
    settings: RunSettings,
    inputs: _Inputs,
    external: External,
    chosen: Sequence[Case],
) -> tuple[Target, list[Result], tuple[float, float]]:
    """Run the cases. Give the target tested, the results, and when the run started and
    ended (time.time()). Exit with status 2 when the harness cannot listen or start."""
    if external is None:
        quiet_reference_logs()
    options = RunOptions(
        timeout_scale=settings.timeout_scale,
        seed=settings.seed,
        concurrency=settings.concurrency,
        repeat=settings.runs,
        impair=inputs.impairment,
        capture=settings.capture,
        session_wait=settings.session_wait,
        connect_timeout=settings.tested.connect_timeout,
    )
    clock, why = arrival_clock()
    if clock != "kernel":
        output.notice(
            f"datagrams are timed when the harness reads them, not when they came: {why}"
            " (D-RSP-26, D-RCTP-33)"
        )
    faults = faults_named(settings.tested.faults)
    started = time.time()
    try:
        run = _run(external, inputs.declared, faults, chosen, options, output, settings.verbose)
        target, results = asyncio.run(run)
    except OSError as error:
        _cannot_start(output, settings.tested, error)
    return target, results, (started, time.time())


def _cannot_start(output: Output, tested: TargetSettings, error: OSError) -> NoReturn:
    """Say why the harness could not listen, or start the embedded reference. Exit 2."""
    why = error.strerror or str(error)
    if tested.listen is not None:
        output.problem("run", f"cannot listen on --listen {described(tested.listen)}: {why}")
    else:
        output.problem("run", f"cannot start the embedded reference: {why}")
    sys.exit(2)


def _recorded(settings: RunSettings) -> dict[str, Any]:
    """The settings that the JSON report records."""
    return {
        "seed": settings.seed,
        "repeat": settings.runs,
        "verify": settings.verify,
        "timeout_scale": settings.timeout_scale,
        "impair": settings.impair,
        "arrival_clock": arrival_clock()[0],
    }


async def _run(
    external: External,
    declared: Ics,
    faults: frozenset[Fault],
    chosen: Sequence[Case],
    options: RunOptions,
    output: Output,
    verbose: bool,
) -> tuple[Target, list[Result]]:
    """Run the chosen cases of the roles the target plays, with a progress bar."""
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
                    _live(output, result, verbose)

                results = await run_cases(cases, target, options, done)
        return target, results


def _live(output: Output, result: Result, verbose: bool) -> None:
    """Show a result as it comes: failures and errors, and with -v every result."""
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


@contextlib.asynccontextmanager
async def _target(
    external: External, declared: Ics, faults: frozenset[Fault], output: Output
) -> AsyncIterator[Target]:
    """The target for the cases. It listens for a client or local system, or starts the
    embedded reference, for as long as the run lasts."""
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


#: What to give `run` to test each role.
_HOW = {
    Role.SERVER: "an RCTP server: --target",
    Role.ROBOT: "an RSP robot: --rsp-target",
    Role.CLIENT: "an RCTP client: --role client --listen",
    Role.LOCAL: "an RSP local system: --role local --listen",
}


def _left_out(cases: Sequence[Case], tested: str) -> str:
    """Say which chosen cases test a role that `tested` does not play, and how to test it."""
    roles = Counter(case.role for case in cases)
    each = "; ".join(f"{plural(n, 'case')} of {_HOW[role]}" for role, n in roles.items())
    return f"left out, as {tested} does not play their role: {each}"


def _check_roles(tested: TargetSettings) -> None:
    """Refuse options that do not go together, for the role tested."""
    target, rsp_target, listen = tested.target, tested.rsp_target, tested.listen
    model = tested.model
    if rsp_target is not None and model is None:
        raise click.UsageError("--rsp-target needs the robot's --model")
    if tested.role == "client":
        if listen is None:
            raise click.UsageError("--role client needs --listen PORT for the client to connect")
        if target is not None or rsp_target is not None:
            raise click.UsageError("--role client tests a client: leave out --target/--rsp-target")
    elif tested.role == "local":
        if listen is None or model is None:
            raise click.UsageError("--role local needs --listen PORT and the --model to play")
        if target is not None or rsp_target is not None:
            raise click.UsageError("--role local tests a local system: leave out the targets")
    elif listen is not None:
        raise click.UsageError("--listen is for --role client and --role local")
    if tested.faults and (target is not None or rsp_target is not None or listen is not None):
        raise click.UsageError("--fault is for the embedded reference: leave out the targets")
    if (tested.rcml is not None or tested.site is not None) and target is None:
        raise click.UsageError("--rcml and --site describe --target: give --target too")
    if model is not None and rsp_target is None and tested.role != "local":
        raise click.UsageError(
            "--model describes --rsp-target, or the robot --role local plays: give one of them"
        )


def _write_reports(
    output: Output,
    results: list[Result],
    registry: dict[str, Case],
    target: Target,
    settings: RunSettings,
    span: tuple[float, float],
    shaky: list[Unstable] | None,
) -> None:
    """Write the reports that the settings ask for. `span`: when the run started and ended
    (time.time()). `shaky`: the unstable cases, None without --verify."""
    files = settings.reports
    try:
        if files.junit is not None:
            files.junit.write_bytes(to_junit(results, registry, *span, shaky or ()))
        if files.json is None and files.html is None:
            return
        report = to_json(results, registry, target.name, _recorded(settings), span, shaky)
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
    output: Output,
    results: list[Result],
    registry: dict[str, Case],
    target: Target,
    shaky: list[Unstable] | None,
) -> None:
    """Show each failure and error, each unstable case, the verdicts by area, and a summary
    line. `shaky`: the unstable cases, None without --verify."""
    from rcmlconf.specs import requirements

    texts = requirements()
    for result in results:
        if result.verdict not in (Verdict.FAIL, Verdict.ERROR):
            continue
        label = f"{result.verdict.value.upper()}{' (known)' if result.known else ''}"
        output.out.line([(label, _STYLE[result.verdict]), (f" {result.case}", "bold")])
        for name, text in explain(result, registry[result.case], texts):
            output.out.line([(f"  {name:>11}  ", "dim"), (text, "")])
    for found in shaky or []:
        _unstable(output, found, [r for r in results if r.case == found.case])
    _table(output, results, registry)
    _notices(output, results, target)
    tally = counts(results)
    fresh = new_failures(results)
    line = ", ".join(f"{n} {v.value}" for v, n in tally.items() if n)
    line += f"; {len(shaky)} unstable" if shaky is not None else ""
    output.summary(f"{target.name}: {len(results)} results: {line}", not fresh and not shaky)


def _unstable(output: Output, found: Unstable, runs: list[Result]) -> None:
    """An unstable case: its verdicts, and each run whose verdict is not the most frequent."""
    output.out.line([("UNSTABLE", "bold red"), (f" {found.case}", "bold"), (f"  {found}", "")])
    usual = found.verdicts[0][0]
    for result in (r for r in runs if r.verdict is not usual):
        said = result.verdict.value + (f": {result.reason}" if result.reason else "")
        output.out.line([(f"  {f'run {result.run}':>11}  ", "dim"), (said, "")])


def _notices(output: Output, results: list[Result], target: Target) -> None:
    """Say how many passes checked only part of their requirement, and which cases the run
    gave up on."""
    partly = sum(1 for r in results if r.verdict is Verdict.PASS and r.reason.startswith(PARTLY))
    if partly:
        output.notice(
            f"{partly} {'pass' if partly == 1 else 'passes'} checked only part of the"
            " requirement, as the target could not show the rest (run -v or --json says which"
            " part and why)"
        )
    skipped = [r for r in results if r.reason.startswith(NOT_RUN)]
    if skipped:  # GiveUp gives each the same reason
        not_run = f"{plural(len(skipped), 'case')} {skipped[0].reason}"
        output.notice(f"gave up on {target.name}: {not_run}")


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


def _roles(tested: TargetSettings) -> set[Role] | None:
    """The roles a run with these settings tests. None: every role (the embedded reference)."""
    if tested.target is not None or tested.rsp_target is not None:
        given = ((Role.SERVER, tested.target), (Role.ROBOT, tested.rsp_target))
        return {role for role, address in given if address is not None}
    if tested.listen is not None:
        return {Role.CLIENT if tested.role == "client" else Role.LOCAL}
    return None
