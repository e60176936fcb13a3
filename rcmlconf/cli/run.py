"""`rcmlconf run`: the conformance suite against an implementation, or the embedded reference."""

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
from rcmlconf.cli.hosts import Address, address_option, listen_option
from rcmlconf.cli.params import Bounded
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
    report_option,
    robot_file,
    site_option,
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
from rcmlconf.conformance.ics import EVERYTHING, Ics, load_ics
from rcmlconf.conformance.probes.clients import HARNESS_RCML
from rcmlconf.conformance.registry import SESSION_WAIT, Case, Role, all_cases
from rcmlconf.conformance.reports.baseline import load_baseline, mark_known
from rcmlconf.conformance.reports.html import to_html
from rcmlconf.conformance.reports.json_report import to_json
from rcmlconf.conformance.reports.junit import to_junit
from rcmlconf.conformance.reports.summary import counts, explain, new_failures, run_status
from rcmlconf.conformance.runner import (
    CONNECT_TIMEOUT,
    PARTLY,
    RunOptions,
    run_cases,
    under_test,
)
from rcmlconf.conformance.targets import Target, embedded_reference, quiet_reference_logs
from rcmlconf.conformance.verdicts import Result, Verdict
from rcmlconf.impair.spec import MOST_BURST, MOST_TIME, parse_impairment
from rcmlconf.rcml.model import RcmlDocument
from rcmlconf.rctp.url import DEFAULT_PORT as RCTP_PORT
from rcmlconf.reference.faults import Fault, describe, faults_named
from rcmlconf.rsp.model import RobotModel
from rcmlconf.validate.validator import load_robot, load_robot_model
from rcmlconf.wording import plural

#: D-RSP-9.
RSP_PORT = 7340
_STYLE = {
    Verdict.PASS: "green",
    Verdict.FAIL: "bold red",
    Verdict.INCONCLUSIVE: "yellow",
    Verdict.NOT_APPLICABLE: "dim",
    Verdict.ERROR: "magenta",
}


@click.command()
@click.option(
    "--target",
    metavar="HOST[:PORT]",
    callback=address_option(RCTP_PORT),
    help=f"An RCTP/2.0 server under test (port {RCTP_PORT} by default; IPv6 in brackets:"
    " [::1]:7330).",
)
@click.option(
    "--rcml",
    type=click.Path(exists=True, dir_okay=False, path_type=Path),
    help="The RCML file of --target's robot: the cases pick its nodes from it. With --role"
    " client: the robot the harness plays (default: its own, D-RCTP-31).",
)
@click.option(
    "--site",
    metavar="PATH",
    callback=site_option,
    help="--target's site path, the target of CONNECT (default: the RCML's).",
)
@click.option(
    "--rsp-target",
    metavar="HOST[:PORT]",
    callback=address_option(RSP_PORT),
    help=f"An RSP robot under test (port {RSP_PORT} by default); needs --model.",
)
@click.option(
    "--model",
    type=click.Path(exists=True, dir_okay=False, path_type=Path),
    help="The robot model (.rmodel) of --rsp-target, or of the robot the harness plays to the"
    " local system under test (--role local).",
)
@click.option(
    "--ics",
    type=click.Path(exists=True, dir_okay=False, path_type=Path),
    help="Implementation conformance statement (TOML): optional features the target lacks.",
)
@click.option(
    "--role",
    type=click.Choice(["server", "client", "local"]),
    default="server",
    show_default=True,
    help="client: the harness plays the server and tests the RCTP client that connects to"
    " --listen, once per case (reconnect it after each). local: the harness plays a robot of"
    " --model and tests the RSP local system that sends to --listen, one run of the scenario of"
    " specs/rsp.md D-RSP-24 per case (start it again after each).",
)
@click.option(
    "--listen",
    metavar="[HOST:]PORT",
    callback=listen_option("127.0.0.1"),
    help="With --role client or local: where the implementation under test connects or sends"
    " (127.0.0.1 by default).",
)
@click.option(
    "--client-command",
    metavar="'CMD {url}'",
    help="With --role client or local: start the implementation under test for each case, {url}"
    " replaced by the case's URL (client: rctp://HOST:PORT/<case id>, D-RCTP-31) or the address"
    " to send to (local: HOST:PORT). No shell reads it. It is stopped (its process group) when"
    " the case ends; its exit status and last lines of output are in the case's report. Without"
    " it, start your implementation yourself: a line says where each case waits.",
)
@click.option(
    "--connect-timeout",
    type=Bounded(0.1, 3600),
    default=CONNECT_TIMEOUT,
    show_default=True,
    metavar="SECONDS",
    help="With --role client or local: how long each case waits for its client to connect (or"
    " its local system's HELLO), before the case's own clock starts. Once a case got none while"
    " none had ever come, the rest give up at once (exit 2).",
)
@click.option("--list", "list_only", is_flag=True, help="List the cases that would run; run none.")
@click.option(
    "--strict",
    is_flag=True,
    help="An inconclusive case fails the run (status 1), as in h2spec's strict mode: a case that"
    " could not tell is not a pass.",
)
@click.option(
    "--only", multiple=True, metavar="GLOB", help="Run the cases whose ID matches (* ? [seq])."
)
@click.option("--skip", multiple=True, metavar="GLOB", help="Leave out the cases whose ID matches.")
@click.option("--repeat", type=click.IntRange(1, 1000), default=1, show_default=True)
@click.option(
    "--timeout-scale",
    type=Bounded(0.1, 100),
    default=1.0,
    show_default=True,
    help="Multiply every case's timeout (a slow target, a loaded CI machine).",
)
@click.option(
    "--session-wait",
    type=Bounded(SESSION_WAIT, 3600),
    default=SESSION_WAIT,
    show_default=True,
    metavar="SECONDS",
    help="The longest session timeout (D-RCTP-11) the five cases that wait one out wait for;"
    " a server announcing longer makes them inconclusive. A server's is 60 s unless it says"
    " otherwise: give 60 to wait for it, at about a minute a case.",
)
@click.option("--seed", type=int, default=0, show_default=True, help="Seeds every impairment.")
@click.option(
    "--impair",
    metavar="SPEC",
    help="Impair the UDP flows of every case with no impairment of its own, e.g."
    " loss=5%,delay=40ms (items KEY=VALUE, comma-separated). Keys: loss, reorder, duplicate,"
    f" corrupt (0 to 100%); delay, jitter, gap (0 to {MOST_TIME:g}s, in ms, s or us); burst"
    f" (the mean run of losses, 1 to {MOST_BURST:.0f}). A failure the impairment can explain is"
    " inconclusive.",
)
@click.option(
    "--concurrency",
    type=click.IntRange(1, 256),
    default=16,
    show_default=True,
    help="Cases in flight at once (those that share state run alone).",
)
@report_option("--junit", "junit", "JUnit XML here.")
@report_option(
    "--json",
    "json_file",
    "JSON here, as its JSON Schema in the package says (run-report.schema.json).",
)
@report_option(
    "--html",
    "html_file",
    "An HTML page here, one self-contained file: verdicts by area, filters, and each case's"
    " requirement, outcome and exchange.",
)
@click.option(
    "--baseline",
    type=click.Path(exists=True, dir_okay=False, path_type=Path),
    help="Known failures (case IDs a line, or an earlier --json): only new ones fail the run.",
)
@click.option(
    "--capture",
    type=click.Path(file_okay=False, path_type=Path),
    help="Write a pcap of each case's traffic into this directory (rcmlconf dissect reads it).",
)
@click.option(
    "--fault",
    "faults",
    multiple=True,
    type=click.Choice([f.value for f in Fault]),
    metavar="NAME",
    help="Without a target: make the embedded reference misbehave (see `rcmlconf serve --help`"
    " and `rcmlconf robot --help` for the names), to watch the suite catch it.",
)
@click.option("-v", "--verbose", is_flag=True, help="A line for every case, passes too.")
def run(
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
    """Run the conformance cases against an implementation and give each a verdict.

    With no target, the embedded reference implementation (an RCTP/2.0 server of the rover
    robot and RSP robots of the CUBO model) is started and tested: every case passes there.

    Verdicts: pass; fail (the target broke the requirement named); inconclusive (the case could
    not tell); not applicable (the target lacks an optional feature, or the robot a kind of
    node); error (the harness or the network failed, not the target).

    Every option and file is checked, and the targets reached once, before any case runs.

    Exit status: 0 when nothing failed but what --baseline lists, 1 when a case failed (or, with
    --strict, was inconclusive), 2 for a usage error, a target that cannot be reached, a run in
    which no case passed or failed, or when the harness could not do its job.

    \b
    Examples:
      rcmlconf run                           # the embedded reference
      rcmlconf run --target robot.local --rcml rover.rcml --junit run.xml
      rcmlconf run --only 'rctp/msg/*' --html report.html
      rcmlconf run --rsp-target 10.0.0.7 --model cubo.rmodel --only 'rsp/*'
      rcmlconf run --only 'rsp/*' --repeat 20 --impair loss=5%,reorder=2%
      rcmlconf run --role client --listen 7330   # then start your client
      rcmlconf run --role client --listen 7330 --client-command 'my-client {url}'
      rcmlconf run --role local --listen 7340 --model cubo.rmodel
      rcmlconf run --fault acquire-not-exclusive # the suite catches a bug
      rcmlconf run --list
    """
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
        timeout_scale, seed, concurrency, repeat, impairment, capture, session_wait, connect_timeout
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
