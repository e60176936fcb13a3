"""`rcmlconf local MODEL --robot HOST:PORT`: the simulacrum, driving a robot and watching it."""

from __future__ import annotations

import asyncio
import sys
import time
from collections.abc import Mapping, Sequence
from pathlib import Path

import click

from rcmlconf.cli.client.values import parse_typed_value, values_json, values_text
from rcmlconf.cli.console import Output
from rcmlconf.cli.interrupts import Interrupts
from rcmlconf.cli.models import load_or_exit
from rcmlconf.cli.rsp_options import ENCRYPTIONS, parse_address, psk_option, read_psk
from rcmlconf.errors import EncodeError, ValueTextError
from rcmlconf.reference.rsp.robot import DEFAULT_PORT
from rcmlconf.reference.rsp.simulacrum import NoSession, Simulacrum
from rcmlconf.rsp.model import Device, RobotModel
from rcmlconf.rsp.reliable import Backlog
from rcmlconf.rsp.session import events
from rcmlconf.validate.validator import load_robot_model
from rcmlconf.values import Value
from rcmlconf.wording import plural

Assignments = tuple[tuple[str, str], ...]


@click.command()
@click.argument("model_path", metavar="MODEL.rmodel", type=click.Path(path_type=Path))
@click.option(
    "--robot",
    "robot_text",
    required=True,
    metavar="HOST[:PORT]",
    help=f"The robot's address (port {DEFAULT_PORT} if not given, D-RSP-9).",
)
@click.option(
    "--period",
    type=click.FloatRange(0.005, 10),
    metavar="SECONDS",
    help="T, a DOWNLINK every T (D-RSP-13). Default: the model's period.",
)
@click.option(
    "--write",
    "writes",
    nargs=2,
    multiple=True,
    metavar="EFFECTOR FIELD=VALUE",
    help="Send this effector value in every DOWNLINK (repeat for each field; arrays as a,b,c).",
)
@click.option(
    "--activate",
    "activates",
    multiple=True,
    metavar="MODULE",
    help="Activate a module (its effectors act, its sensors report).",
)
@click.option(
    "--watch",
    "watches",
    multiple=True,
    metavar="DEVICE",
    help="Request a sensor, monitor, event or memory event and print what comes.",
)
@click.option(
    "--issue",
    "issues",
    nargs=2,
    multiple=True,
    metavar="COMMAND FIELD=VALUE",
    help="Issue a command or memory command once (repeat for each field).",
)
@click.option(
    "--duration",
    type=click.FloatRange(0, min_open=True),
    metavar="SECONDS",
    help="Stop after this long. Default: at Ctrl-C.",
)
@click.option(
    "--encryption",
    type=click.Choice(list(ENCRYPTIONS)),
    default="none",
    show_default=True,
    help="The session's AEAD (D-RSP-21).",
)
@psk_option
@click.option(
    "--format",
    "format_",
    type=click.Choice(["text", "json"]),
    default="text",
    show_default=True,
    help="json: one JSON object per line for each change and occurrence.",
)
def local(
    model_path: Path,
    robot_text: str,
    period: float | None,
    writes: Assignments,
    activates: tuple[str, ...],
    watches: tuple[str, ...],
    issues: Assignments,
    duration: float | None,
    encryption: str,
    psk_file: Path | None,
    format_: str,
) -> None:
    """Open an RSP session with a robot of MODEL.rmodel and drive it as the paper's simulacrum
    does: effector values in a DOWNLINK every T, requested sensors, monitors and events printed
    as they change or occur, commands acknowledged.

    Values are printed when they change, not every T. At the end (--duration or Ctrl-C) the
    session gets BYE and a summary of the packets goes to standard error.

    \b
    Exit status: 0 done; 1 invalid model, or no session (refused or no answer);
      2 usage error.

    \b
    Examples:
      rcmlconf local cubo.rmodel --robot 127.0.0.1 --watch position
      rcmlconf local cubo.rmodel --robot 127.0.0.1 --activate base \\
          --write leftWheel speed=200 --write rightWheel speed=150 \\
          --watch position --duration 5
      rcmlconf local cubo.rmodel --robot 127.0.0.1 --issue irFire code=7 --duration 1
    """
    output = Output()
    model = load_or_exit(output, "local", model_path, load_robot_model)
    address = parse_address(robot_text, DEFAULT_PORT)
    chosen = ENCRYPTIONS[encryption]
    psk = read_psk(psk_file, {chosen})
    plan = _Plan(model, writes, activates, watches, issues)
    simulacrum = Simulacrum(model, address, period=period, encryption=chosen, psk=psk)
    sys.exit(asyncio.run(_run(simulacrum, plan, duration, output, format_ == "json")))


class _Plan:
    """The options, checked against the model before anything is sent."""

    def __init__(
        self,
        model: RobotModel,
        writes: Assignments,
        activates: Sequence[str],
        watches: Sequence[str],
        issues: Assignments,
    ) -> None:
        self.model = model
        self.writes = _grouped(model, writes, "--write")
        self.issues = _grouped(model, issues, "--issue")
        for name in (*activates, *watches):
            _device(model, name, "--activate" if name in activates else "--watch")
        self.activates = tuple(activates)
        self.watches = tuple(watches)

    def apply(self, simulacrum: Simulacrum) -> None:
        try:
            for name in self.activates:
                simulacrum.set_active(name, True)
            for name in self.watches:
                simulacrum.set_active(name, True)
            for name, values in self.writes.items():
                simulacrum.write(name, values)
            for name, values in self.issues.items():
                simulacrum.issue(name, values)
        except (KeyError, TypeError, ValueError, EncodeError, Backlog) as exc:
            raise click.UsageError(str(exc).strip("'\"")) from None


def _device(model: RobotModel, name: str, option: str) -> Device:
    found = model.device(name)
    if found is None:
        names = ", ".join(d.name for d in model.devices)
        raise click.BadParameter(
            f"{model.name} has no device {name!r} (it has {names})", param_hint=option
        )
    return found


def _grouped(model: RobotModel, pairs: Assignments, option: str) -> dict[str, dict[str, Value]]:
    """FIELD=VALUE pairs gathered by device, each value parsed by its field's type."""
    grouped: dict[str, dict[str, Value]] = {}
    for name, assignment in pairs:
        found = _device(model, name, option)
        field_name, equals, text = assignment.partition("=")
        fields = {f.name: f for f in found.fields}
        if not equals or field_name not in fields:
            raise click.BadParameter(
                f"{assignment!r}: give FIELD=VALUE with a field of {name} ({', '.join(fields)})",
                param_hint=option,
            )
        try:
            value = parse_typed_value(fields[field_name].type, text, f"{name}.{field_name}")
        except ValueTextError as exc:
            raise click.BadParameter(str(exc), param_hint=option) from None
        grouped.setdefault(name, {})[field_name] = value
    return grouped


class _Printer:
    """A line for each watched value that changed and each occurrence."""

    def __init__(self, model: RobotModel, output: Output, as_json: bool) -> None:
        self.model = model
        self.output = output
        self.as_json = as_json
        self.start = time.monotonic()
        self.last: dict[str, Mapping[str, Value]] = {}

    def watch(self, simulacrum: Simulacrum, name: str) -> None:
        simulacrum.listen(name, lambda values: self.show(name, values))

    def show(self, name: str, values: Mapping[str, Value]) -> None:
        found = self.model.device(name)
        assert found is not None
        if not found.kind.occurrence and self.last.get(name) == values:
            return
        self.last[name] = values
        elapsed = time.monotonic() - self.start
        if self.as_json:
            document = {"t": round(elapsed, 3), "device": name, "kind": found.kind.value}
            self.output.json_line({**document, "values": values_json(found.fields, values)})
            return
        self.output.live(
            [
                (f"{elapsed:8.3f} ", "dim"),
                (f"{name} ", "bold"),
                (" ".join(values_text(found.fields, values)), ""),
            ]
        )


async def _run(
    simulacrum: Simulacrum, plan: _Plan, duration: float | None, output: Output, as_json: bool
) -> int:
    target = f"{simulacrum.robot[0]}:{simulacrum.robot[1]}"
    try:
        opened = await simulacrum.open()
    except NoSession as exc:
        output.problem("local", f"{target}: {exc}")
        return 1
    except OSError as exc:
        output.problem("local", f"{target}: {exc.strerror or exc}")
        return 1
    output.err.line(
        [
            ("session ", ""),
            (f"{opened.session_id:012x}", "bold"),
            (f" with {target}, T = {opened.period * 1000:g} ms", ""),
        ]
    )
    printer = _Printer(simulacrum.model, output, as_json)
    for name in plan.watches:
        printer.watch(simulacrum, name)
    plan.apply(simulacrum)
    with Interrupts() as interrupts:
        if duration is None:
            await interrupts.wait()
        else:
            await interrupts.race(asyncio.sleep(duration))
    ended = simulacrum.closed
    await simulacrum.aclose()
    _summary(simulacrum, output)
    if isinstance(ended, events.SessionClosed) and ended.by_peer:
        output.notice(f"the robot ended the session: {ended.reason.name.lower()}")
    return 0


def _summary(simulacrum: Simulacrum, output: Output) -> None:
    endpoint = simulacrum.endpoint
    counts = endpoint.received
    acks = sum(isinstance(e, events.Acknowledged) for e in simulacrum.history)
    drops = sum(isinstance(e, events.PacketDropped) for e in simulacrum.history)
    output.err.line(
        [
            (
                f"sent {plural(endpoint.packets_sent, 'packet')}; received {counts.received}"
                f" ({counts.lost} lost, {counts.late} late, {counts.duplicates} duplicates,"
                f" {drops} dropped); {plural(acks, 'occurrence')} acknowledged",
                "dim",
            )
        ]
    )
