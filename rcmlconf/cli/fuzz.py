"""`rcmlconf fuzz`: stateful fuzzing of an RCTP/2.0 server, or of the embedded reference; and
`rcmlconf fuzz replay`, which sends a finding again."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import click

from rcmlconf.cli.params import Bounded
from rcmlconf.cli.target_options import target_options, target_settings
from rcmlconf.conformance.settings import TargetSettings


def _wait_options(command: Any) -> Any:
    command = click.option(
        "--target-command",
        metavar="CMD",
        help="Start the target with CMD (no shell reads it), restart it after a crash or a"
        " hang, and keep its exit status and the end of its stderr in the finding. Its memory"
        " and open files are watched for leaks.",
    )(command)
    return click.option(
        "--timeout-scale",
        type=Bounded(0.1, 100),
        default=1.0,
        show_default=True,
        help="Multiply the 5 s every answer and liveness probe may take (D-FUZZ-4).",
    )(command)


@click.group(invoke_without_command=True)
@target_options
@_wait_options
@click.option("--seconds", type=Bounded(0.1, 7 * 86400), help="Fuzz this long (default 60 s).")
@click.option("--cases", type=click.IntRange(1), help="Run this many test cases, then stop.")
@click.option("--seed", type=int, default=0, show_default=True, help="Seeds every choice.")
@click.option(
    "--state",
    multiple=True,
    metavar="NAME",
    help="Fuzz only in this state (repeatable; states.dot and the report's state map name"
    " them): all of them by default.",
)
@click.option(
    "--kind",
    multiple=True,
    metavar="NAME",
    help="Begin each case only with this mutation kind (repeatable; the state map's columns):"
    " all of them by default.",
)
@click.option(
    "--out",
    type=click.Path(file_okay=False, path_type=Path),
    default=Path("rcmlconf-fuzz"),
    show_default=True,
    help="The campaign's folder: finding-N.json and .pcap, report.json, state.json, states.dot"
    " (and states.png with Graphviz).",
)
@click.option(
    "--resume",
    type=click.Path(file_okay=False, exists=True, path_type=Path),
    help="Go on with the campaign in this folder: its state map, corpus and findings.",
)
@click.option(
    "--max-rate",
    type=Bounded(0.1, 1_000_000),
    help="Test cases a second at most (default: unbounded on loopback, 200 elsewhere).",
)
@click.option(
    "--max-memory",
    type=click.IntRange(64),
    default=512,
    show_default=True,
    metavar="MiB",
    help="The fuzzer's own memory: past it the corpus is trimmed.",
)
@click.option("--leak-rss", type=click.IntRange(1), default=50, show_default=True, metavar="MiB")
@click.option("--leak-fds", type=click.IntRange(1), default=100, show_default=True, metavar="N")
@click.option("--json", "json_file", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--junit", type=click.Path(dir_okay=False, path_type=Path))
@click.pass_context
def fuzz(ctx: click.Context, /, **options: Any) -> None:
    """Fuzz an RCTP/2.0 server or client, or an RSP robot or local system, through its states;
    keep each finding minimised.

    Each test case drives the target to a state with valid requests (a session, a privilege,
    a stream set up or playing, an event access playing, a session closing), sends mutated
    messages there (on the control connection and on the data stream), and judges what came
    back: a crash, a hang, or a violation of a MUST of specs/ (the requirement is named). Under
    --target-command a leak is a finding too. Effort goes where the state map is thin.

    An RSP robot (--rsp-target with --model) is taken through a session (welcomed, an
    effector driven, a module active, a memory command sent) and sent mutated DOWNLINKs: header
    fields, Device Map bits (past the model's devices too), payloads, lengths.

    With --role client the fuzzer plays the server of the harness's robot (D-FUZZ-8): it starts
    --client-command for each case on rctp://HOST:PORT/ (--listen), waits until the client's
    scenario (D-RCTP-31) enters the case's state, and sends a mutated answer, mutated requests
    of the server's or mutated datagrams; then a BYE. A crash is the client closing while it
    owes an answer, or its process ending badly before its run did; a hang, an answer owed for
    5 s. Without --client-command the embedded reference client is fuzzed.

    With --role local the fuzzer plays a robot of --model (D-FUZZ-9) to the RSP local system
    --client-command starts for each case, {url} being the robot's HOST:PORT (--listen): it
    mutates the WELCOME, or the UPLINKs, ACKs and BYEs once the local system is welcomed or has
    taken a memory event. A crash is its process ending badly before its run did; a hang, 5 s
    without a packet from it. Without --client-command the embedded reference local system is
    fuzzed (`rcmlconf local --scenario`).

    With no target, the embedded reference server is started as a process of its own and
    fuzzed; with --model and no target, the embedded reference robot of that model.

    Each finding is minimised (steps, then bytes), re-run 3 times, and written as
    finding-N.json and finding-N.pcap; `rcmlconf fuzz replay` sends it again.

    Exit status: 0 no finding, 1 findings, 2 a usage error or a target that cannot be reached.

    \b
    Examples:
      rcmlconf fuzz --seconds 30                       # the embedded reference
      rcmlconf fuzz --target 127.0.0.1:7330 --rcml robot.rcml --seconds 600 --out run1
      rcmlconf fuzz --target 127.0.0.1:7330 --rcml robot.rcml \\
          --target-command 'my-server --port 7330' --junit fuzz.xml
      rcmlconf fuzz --rsp-target 127.0.0.1:7340 --model cubo.rmodel --seconds 120
      rcmlconf fuzz --model cubo.rmodel --seconds 60     # the embedded reference robot
      rcmlconf fuzz --role client --listen 7400 --client-command 'my-client --url {url}'
      rcmlconf fuzz --role local --model robot.rmodel --client-command 'my-local {url}'
      rcmlconf fuzz --resume run1 --target 127.0.0.1:7330 --rcml robot.rcml --seconds 600
      rcmlconf fuzz replay run1/finding-1.json --target 127.0.0.1:7330 --rcml robot.rcml
    """
    if ctx.invoked_subcommand is not None:
        ctx.obj = options
        return
    from rcmlconf.cli.fuzz_run import fuzz_target

    tested = target_settings(options)
    _check_role(tested)
    fuzz_target(tested, options)


def _check_role(tested: TargetSettings) -> None:
    if tested.role != "server" and (tested.target or tested.rsp_target):
        raise click.UsageError(
            f"--role {tested.role} plays the other side: leave out --target/--rsp-target"
        )
    if tested.target is not None and tested.rsp_target is not None:
        raise click.UsageError("give --target or --rsp-target: one campaign fuzzes one target")


@fuzz.command()
@click.argument("finding", type=click.Path(dir_okay=False, exists=True, path_type=Path))
@target_options
@_wait_options
def replay(finding: Path, **options: Any) -> None:
    """Send a finding (finding-N.json) to the target again and say whether it reproduces.

    Exit status: 1 it reproduced, 0 it did not, 2 a usage error or an unreachable target.
    """
    from rcmlconf.cli.fuzz_run import replay_finding

    tested = target_settings(options)
    _check_role(tested)
    replay_finding(finding, tested, options)
