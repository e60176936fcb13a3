"""`rcmlconf run`: the conformance suite against an implementation, or the embedded reference.

This module declares the options and turns them into one `RunSettings`.
The run itself (`run_suite`) is imported only after that. A bad option is then refused
without loading the harness, whose imports take three times as long as these.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import click

from rcmlconf.cli.params import Bounded
from rcmlconf.cli.run_options import report_option
from rcmlconf.cli.target_options import target_options, target_settings
from rcmlconf.conformance.run_defaults import SESSION_WAIT
from rcmlconf.conformance.settings import ReportFiles, RunSettings
from rcmlconf.impair.spec import MOST_BURST, MOST_TIME


@click.command()
@target_options
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
    "--verify",
    type=click.IntRange(2, 1000),
    is_flag=False,
    flag_value=10,
    default=None,
    metavar="[N]",
    help="Run each case N times (10 if no N) and report each case whose verdicts differ as"
    " unstable, which fails the run (status 1); e.g. --verify 20 --only 'rsp/local/*'. Not"
    " with --repeat.",
)
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
@click.option("-v", "--verbose", is_flag=True, help="A line for every case, passes too.")
def run(**options: Any) -> None:
    """Run the conformance cases against an implementation and give each a verdict.

    With no target, the embedded reference implementation (an RCTP/2.0 server of the rover
    robot and RSP robots of the CUBO model) is started and tested: every case passes there.

    Verdicts: pass; fail (the target broke the requirement named); inconclusive (the case could
    not tell); not applicable (the target lacks an optional feature, or the robot a kind of
    node); error (the harness or the network failed, not the target).

    Every option and file is checked, and the targets reached once, before any case runs.

    Exit status: 0 when nothing failed but what --baseline lists, 1 when a case failed (or, with
    --strict, was inconclusive; with --verify, was unstable), 2 for a usage error, a target that
    cannot be reached, a run in which no case passed or failed, or when the harness could not
    do its job.

    \b
    Examples:
      rcmlconf run                           # the embedded reference
      rcmlconf run --target robot.local --rcml rover.rcml --junit run.xml
      rcmlconf run --only 'rctp/msg/*' --html report.html
      rcmlconf run --rsp-target 10.0.0.7 --model cubo.rmodel --only 'rsp/*'
      rcmlconf run --only 'rsp/*' --repeat 20 --impair loss=5%,reorder=2%
      rcmlconf run --verify 20 --only 'rsp/local/*'   # unstable verdicts fail
      rcmlconf run --role client --listen 7330   # then start your client
      rcmlconf run --role client --listen 7330 --client-command 'my-client {url}'
      rcmlconf run --role local --listen 7340 --model cubo.rmodel
      rcmlconf run --fault acquire-not-exclusive # the suite catches a bug
      rcmlconf run --list
    """
    _check_verify(options)
    settings = run_settings(options)
    from rcmlconf.cli.run_suite import run_suite

    run_suite(settings)


def _check_verify(options: dict[str, Any]) -> None:
    """Refuse --verify with --repeat: --verify N sets how many runs each case gets."""
    given = click.get_current_context().get_parameter_source("repeat")
    if options["verify"] is not None and given is not click.ParameterSource.DEFAULT:
        raise click.UsageError("--verify N runs each case N times: leave out --repeat")


def run_settings(options: dict[str, Any]) -> RunSettings:
    """`run`'s options, taken out of `options` (click's, by parameter name). An option left
    over is a bug: RunSettings has no field for it."""
    settings = RunSettings(
        tested=target_settings(options),
        reports=ReportFiles(
            junit=options.pop("junit"), json=options.pop("json_file"), html=options.pop("html_file")
        ),
        list_only=options.pop("list_only"),
        strict=options.pop("strict"),
        only=options.pop("only"),
        skip=options.pop("skip"),
        repeat=options.pop("repeat"),
        verify=options.pop("verify"),
        timeout_scale=options.pop("timeout_scale"),
        session_wait=options.pop("session_wait"),
        seed=options.pop("seed"),
        impair=options.pop("impair"),
        concurrency=options.pop("concurrency"),
        baseline=options.pop("baseline"),
        capture=options.pop("capture"),
        verbose=options.pop("verbose"),
    )
    if options:
        raise TypeError(f"RunSettings has no field for {', '.join(sorted(options))}")
    return settings
