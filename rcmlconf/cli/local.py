"""`rcmlconf local MODEL --robot HOST:PORT`: the simulacrum, driving a robot and watching it.

Every option is checked against the model, and what it asks for handed to the simulacrum, before
HELLO: a bad one is a usage error and no packet. Once the robot has opened a session, whatever
ends the command (--duration, Ctrl-C or SIGTERM, the output's reader going away) ends it with BYE,
or the robot would refuse every local system as busy until its 10 s timeout (D-RSP-12, R-RSP-22).
A session that ends first (the robot's BYE, 10 s without a packet from it: D-RSP-13) ends the
command too, as a failure: whatever the robot does, the command ends by itself.
"""

from __future__ import annotations

import asyncio
import sys
import time
from collections.abc import Awaitable, Callable, Mapping, Sequence
from pathlib import Path

import click

from rcmlconf.cli.client.values import parse_typed_value, values_json
from rcmlconf.cli.console import Output
from rcmlconf.cli.hosts import Address, address_option
from rcmlconf.cli.interrupts import Interrupts
from rcmlconf.cli.models import load_or_exit
from rcmlconf.cli.params import DAY, Bounded, seconds
from rcmlconf.cli.rsp_options import ENCRYPTIONS, psk_option, read_psk
from rcmlconf.errors import EncodeError, ValueTextError
from rcmlconf.reference.rsp.robot import DEFAULT_PORT
from rcmlconf.reference.rsp.simulacrum import NoSession, Simulacrum, session_end
from rcmlconf.rsp.codec.bodies import MAX_PERIOD_MS, MIN_PERIOD_MS
from rcmlconf.rsp.model import Device, DeviceKind, RobotModel
from rcmlconf.rsp.reliable import Backlog
from rcmlconf.rsp.session import events
from rcmlconf.validate.validator import load_robot_model
from rcmlconf.values import Value
from rcmlconf.values.shown import values_text
from rcmlconf.wording import indefinite, one_of, plural

Assignments = tuple[tuple[str, str], ...]
_K = DeviceKind
#: What each option takes (D-RSP-14, D-RSP-17, D-RSP-18).
_TAKES = {
    "--write": (_K.EFFECTOR,),
    "--activate": (_K.MODULE,),
    "--watch": (_K.SENSOR, _K.MONITOR, _K.EVENT, _K.MEMORY_EVENT),
    "--issue": (_K.COMMAND, _K.MEMORY_COMMAND),
}
#: What the simulacrum may still refuse of a device whose name, kind and values `_Plan` took: a
#: value the codec cannot carry, or more occurrences than may wait.
_REFUSED = (KeyError, TypeError, ValueError, EncodeError, Backlog)


@click.command()
@click.argument("model_path", metavar="MODEL.rmodel", type=click.Path(path_type=Path))
@click.option(
    "--robot",
    "robot",
    required=True,
    metavar="HOST[:PORT]",
    callback=address_option(DEFAULT_PORT),
    help=f"The robot's address (port {DEFAULT_PORT} if not given, D-RSP-9).",
)
@click.option(
    "--period",
    type=Bounded(MIN_PERIOD_MS / 1000, MAX_PERIOD_MS / 1000),
    metavar="SECONDS",
    help="T, a DOWNLINK every T (D-RSP-13; whole milliseconds). Default: the model's period.",
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
    type=seconds(DAY),
    metavar="SECONDS",
    help="Stop after this long (at most a day). Default: at Ctrl-C.",
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
    "--scenario",
    is_flag=True,
    help="Run the conformance scenario of a local system once (specs/rsp.md D-RSP-24), as the"
    " embedded reference runs it for `rcmlconf run --role local`; the other options but"
    " --psk-file are left aside. Exit 0 once the run ends.",
)
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
    robot: Address,
    period: float | None,
    writes: Assignments,
    activates: tuple[str, ...],
    watches: tuple[str, ...],
    issues: Assignments,
    duration: float | None,
    encryption: str,
    psk_file: Path | None,
    scenario: bool,
    format_: str,
) -> None:
    """Open an RSP session with a robot of MODEL.rmodel and drive it as the paper's simulacrum
    does: effector values in a DOWNLINK every T, requested sensors, monitors and events printed
    as they change or occur, commands acknowledged.

    Values are printed when they change, not every T. Every option is checked against the model
    before anything is sent. At the end (--duration, Ctrl-C, or the reader of the output gone)
    the session gets BYE and a summary of the packets goes to standard error.

    \b
    Exit status: 0 done; 1 invalid model, no session (refused or no answer), or a session
      that ended first (the robot's BYE, or 10 s without a packet from it);
      2 usage error or unreadable model.

    \b
    Examples:
      rcmlconf local cubo.rmodel --robot 127.0.0.1 --watch position
      rcmlconf local cubo.rmodel --robot 127.0.0.1 --activate base \\
          --write leftWheel speed=200 --write rightWheel speed=150 \\
          --watch position --duration 5
      rcmlconf local cubo.rmodel --robot 127.0.0.1 --issue irFire code=7 --duration 1
      rcmlconf local cubo.rmodel --robot 127.0.0.1:17340 --scenario   # D-RSP-24, once
    """
    output = Output()
    model = load_or_exit(output, "local", model_path, load_robot_model)
    if scenario:
        from rcmlconf.conformance.probes.local_scenario import reference_local

        key = read_psk(psk_file, set())
        asyncio.run(reference_local(model, key, robot))
        sys.exit(0)
    chosen = ENCRYPTIONS[encryption]
    psk = read_psk(psk_file, {chosen})
    plan = _Plan(model, writes, activates, watches, issues)
    simulacrum = Simulacrum(model, robot, period=period, encryption=chosen, psk=psk)
    printer = _Printer(model, output, format_ == "json")
    plan.apply(simulacrum, printer)
    status = asyncio.run(_run(simulacrum, printer, duration, output))
    if printer.failed is not None:
        raise printer.failed  # the console's entry point reports a lost output
    sys.exit(status)


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
        self.writes = _grouped(model, writes, "--write")
        self.activates = [_device(model, name, "--activate").name for name in activates]
        self.watches = [_device(model, name, "--watch").name for name in watches]
        self.issues = _grouped(model, issues, "--issue")

    def apply(self, simulacrum: Simulacrum, printer: _Printer) -> None:
        """All of it handed to the simulacrum, which holds it until the session opens: whatever
        it refuses is refused before HELLO. Effector values first, so that a module activated
        with them acts from the first DOWNLINK."""
        for name, values in self.writes.items():
            _handed("--write", name, simulacrum.write, name, values)
        for name in self.activates:
            _handed("--activate", name, simulacrum.set_active, name, True)
        for name in self.watches:
            _handed("--watch", name, simulacrum.set_active, name, True)
            printer.watch(simulacrum, name)
        for name, values in self.issues.items():
            _handed("--issue", name, simulacrum.issue, name, values)


def _handed(option: str, name: str, call: Callable[..., object], *args: object) -> None:
    try:
        call(*args)
    except _REFUSED as exc:
        why = str(exc).strip("'\"")  # a KeyError's text is the repr of its message
        raise _bad(option, f"{name}: {why}") from None


def _bad(option: str, message: str) -> click.BadParameter:
    return click.BadParameter(message, param_hint=f"'{option}'")


def _device(model: RobotModel, name: str, option: str) -> Device:
    """The device `name` of the model, of a kind `option` takes."""
    kinds = _TAKES[option]
    takes = indefinite(one_of([kind.value for kind in kinds]))
    candidates = ", ".join(d.name for d in model.devices if d.kind in kinds) or "none"
    found = model.device(name)
    if found is None:
        raise _bad(
            option, f"{model.name} has no device {name!r} ({option} takes {takes}: {candidates})"
        )
    if found.kind not in kinds:
        raise _bad(
            option,
            f"{name!r} is {indefinite(found.kind.value)}; {option} takes {takes}"
            f" ({model.name} has {candidates})",
        )
    return found


def _grouped(model: RobotModel, pairs: Assignments, option: str) -> dict[str, dict[str, Value]]:
    """FIELD=VALUE pairs gathered by device, each value parsed by its field's type, each device
    with a value for every field (every packet carries them all)."""
    grouped: dict[str, dict[str, Value]] = {}
    for name, assignment in pairs:
        found = _device(model, name, option)
        field_name, equals, text = assignment.partition("=")
        fields = {f.name: f for f in found.fields}
        if not equals or field_name not in fields:
            raise _bad(
                option,
                f"{name} {assignment!r}: give FIELD=VALUE with a field of {name}"
                f" ({', '.join(fields)})",
            )
        values = grouped.setdefault(name, {})
        if field_name in values:
            raise _bad(option, f"{name} {field_name} is given twice")
        try:
            values[field_name] = parse_typed_value(
                fields[field_name].type, text, f"{name}.{field_name}"
            )
        except ValueTextError as exc:
            raise _bad(option, str(exc)) from None
    for name, values in grouped.items():
        missing = [f.name for f in model.by_name[name].fields if f.name not in values]
        if missing:
            raise _bad(
                option,
                f"{name} has no value for {', '.join(missing)}: give each field"
                f" ({option} {name} FIELD=VALUE, repeated)",
            )
    return grouped


class _Printer:
    """A line for each watched value that changed and each occurrence."""

    def __init__(self, model: RobotModel, output: Output, as_json: bool) -> None:
        self.model = model
        self.output = output
        self.as_json = as_json
        #: When the session opened: each line's time is counted from there.
        self.start = time.monotonic()
        self.last: dict[str, Mapping[str, Value]] = {}
        #: Why standard output could not be written (its reader gone, a full disk): the command
        #: then ends, as other commands do, and the error is reported once the session is closed.
        self.failed: OSError | None = None
        self.stopped = asyncio.Event()

    def watch(self, simulacrum: Simulacrum, name: str) -> None:
        simulacrum.listen(name, lambda values: self.show(name, values))

    def show(self, name: str, values: Mapping[str, Value]) -> None:
        found = self.model.device(name)
        assert found is not None
        if self.failed is not None or (not found.kind.occurrence and self.last.get(name) == values):
            return
        self.last[name] = values
        try:
            self._print(found, values)
        except OSError as exc:  # called by the loop, which would only log it and go on
            self.failed = exc
            self.stopped.set()

    def _print(self, found: Device, values: Mapping[str, Value]) -> None:
        elapsed = time.monotonic() - self.start
        if self.as_json:
            document = {"t": round(elapsed, 3), "device": found.name, "kind": found.kind.value}
            self.output.json_line({**document, "values": values_json(found.fields, values)})
            return
        self.output.live(
            [
                (f"{elapsed:8.3f} ", "dim"),
                (f"{found.name} ", "bold"),
                (" ".join(values_text(found.fields, values)), ""),
            ]
        )


async def _run(
    simulacrum: Simulacrum, printer: _Printer, duration: float | None, output: Output
) -> int:
    target = f"{simulacrum.robot[0]}:{simulacrum.robot[1]}"
    with Interrupts() as interrupts:
        # A Ctrl-C while HELLO awaits its answer (3 s at most) lets the answer come, so that a
        # session the robot opened gets its BYE; only a second one stops waiting.
        try:
            opened = await interrupts.race(simulacrum.open(), count=2)
        except (NoSession, OSError) as exc:
            reason = exc.strerror or exc if isinstance(exc, OSError) else exc
            output.problem("local", f"{target}: {reason}")
            return 1
        if opened is None:
            await simulacrum.aclose()
            output.problem("local", f"{target}: stopped before the robot answered HELLO")
            return 1
        try:
            printer.start = time.monotonic()
            output.err.line(
                [
                    ("session ", ""),
                    (f"{opened.session_id:012x}", "bold"),
                    (f" with {target}, T = {opened.period * 1000:g} ms", ""),
                ]
            )
            await interrupts.race(_until(duration, printer.stopped.wait(), simulacrum.ended()))
            ended = simulacrum.closed  # before BYE: over by itself, or not
        finally:
            await simulacrum.aclose()
    _summary(simulacrum, output)
    if ended is not None:
        output.problem("local", f"{target}: {session_end(ended)}")
        return 1
    return 0


async def _until(duration: float | None, *ends: Awaitable[object]) -> None:
    """Until one of `ends` is done or `duration` seconds have passed (without it, until one
    is done)."""
    waits = [asyncio.ensure_future(end) for end in ends]
    try:
        await asyncio.wait(waits, timeout=duration, return_when=asyncio.FIRST_COMPLETED)
    finally:
        for wait in waits:
            wait.cancel()


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
