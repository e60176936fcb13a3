"""`rcmlconf robot MODEL`: the reference RSP robot, until Ctrl-C."""

from __future__ import annotations

import asyncio
import logging
import sys
from pathlib import Path

import click

from rcmlconf.cli.console import Output
from rcmlconf.cli.interrupts import Interrupts
from rcmlconf.cli.logs import log_lines
from rcmlconf.cli.models import load_or_exit
from rcmlconf.cli.ready import write_ready
from rcmlconf.cli.rsp_options import ENCRYPTIONS, host_only, psk_option, read_psk
from rcmlconf.reference.faults import faults_named, names
from rcmlconf.reference.rsp.robot import DEFAULT_PORT, ReferenceRobot, RobotSettings
from rcmlconf.validate.validator import load_robot_model


@click.command()
@click.argument("model_path", metavar="MODEL.rmodel", type=click.Path(path_type=Path))
@click.option(
    "--host",
    default="127.0.0.1",
    show_default=True,
    callback=host_only,
    help="The address to listen on.",
)
@click.option(
    "--port",
    type=click.IntRange(0, 65535),
    default=DEFAULT_PORT,
    show_default=True,
    metavar="N",
    help="The UDP port (D-RSP-9); 0 picks a free one.",
)
@click.option(
    "--encryption",
    "encryptions",
    type=click.Choice(list(ENCRYPTIONS)),
    multiple=True,
    help="What sessions may use (repeat for several). Default: none.",
)
@psk_option
@click.option("--seed", type=int, default=0, show_default=True, help="The simulation's seed.")
@click.option(
    "--ready-file",
    type=click.Path(dir_okay=False, path_type=Path),
    help='Once listening, write {"host": H, "port": N} there (removed at exit).',
)
@click.option(
    "--fault",
    "faults",
    type=click.Choice(names("robot")),
    multiple=True,
    metavar="NAME",
    help="Misbehave as NAME says (repeat for several): for testing a conformance harness, never "
    "for a real robot. NAME is one of " + ", ".join(names("robot")) + ".",
)
@click.option(
    "-v", "--verbose", count=True, help="A line per session event (-vv: every effector value)."
)
def robot(
    model_path: Path,
    host: str,
    port: int,
    encryptions: tuple[str, ...],
    psk_file: Path | None,
    seed: int,
    ready_file: Path | None,
    faults: tuple[str, ...],
    verbose: int,
) -> None:
    """Run a robot of MODEL.rmodel that speaks RSP on UDP (the reference robot), until Ctrl-C
    or SIGTERM: the packet handler and the motion, sensor, security and audio processors of the
    RSP paper. CUBO gets a simulated body (differential drive, arms, head, sensors); any other
    model a generic one whose monitors echo its effectors.

    One session at a time: a second local system is refused (REFUSED 3). At the end the session
    gets BYE (reason 2, shutdown).

    \b
    Exit status: 0 stopped by Ctrl-C or SIGTERM; 1 invalid model; 2 usage error, unreadable
      model, a port in use, or a ready file that cannot be written.

    \b
    Examples:
      rcmlconf robot rcmlconf/reference/robots/cubo/cubo.rmodel
      rcmlconf robot --encryption aes-256-gcm --psk-file cubo.key -v cubo.rmodel
    """
    output = Output()
    model = load_or_exit(output, "robot", model_path, load_robot_model)
    chosen = {ENCRYPTIONS[name] for name in encryptions or ("none",)}
    psk = read_psk(psk_file, chosen)
    settings = RobotSettings(host, port, frozenset(chosen), psk, seed, faults_named(faults))
    with log_lines(output, verbose, "rcmlconf.robot"):
        sys.exit(asyncio.run(_run(ReferenceRobot(model, settings), output, ready_file)))


async def _run(robot: ReferenceRobot, output: Output, ready_file: Path | None) -> int:
    try:
        await robot.start()
    except OSError as exc:
        settings = robot.settings
        output.problem(
            "robot",
            f"cannot listen on {settings.host} UDP port {settings.port}:"
            f" {exc.strerror or exc}; choose another with --port (0 picks a free one)",
        )
        return 2
    host, port = robot.address
    output.err.line([("robot ", ""), (robot.model.name, "bold"), (f" on UDP {host}:{port}", "")])
    output.err.line([("Ctrl-C to stop", "dim")])
    # Signals are caught before the ready file says so: a script may send one at once.
    with Interrupts() as interrupts:
        ready = {"host": host, "port": port}
        if ready_file is not None and not write_ready(output, "robot", ready_file, ready):
            robot.stop()
            return 2
        try:
            await interrupts.wait()
        finally:
            robot.stop()
            if ready_file is not None:
                ready_file.unlink(missing_ok=True)
    logging.getLogger("rcmlconf.robot").info("stopped")
    return 0
