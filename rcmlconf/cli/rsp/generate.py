"""`rcmlconf rsp generate MODEL.rmodel [-o FILE]`: the paper's module creator (§II.B, Fig. 4)."""

from __future__ import annotations

import sys
from pathlib import Path

import click

from rcmlconf.cli.console import Output
from rcmlconf.cli.models import load_or_exit
from rcmlconf.rsp.generate import generate_module
from rcmlconf.rsp.generate_names import NameClash
from rcmlconf.validate.validator import load_robot_model
from rcmlconf.wording import plural

_COMMAND = "rsp generate"


@click.command()
@click.argument("model_path", metavar="MODEL.rmodel", type=click.Path(path_type=Path))
@click.option(
    "-o",
    "--output",
    "output_path",
    type=click.Path(dir_okay=False, path_type=Path),
    metavar="FILE",
    help="Write the module to FILE (replaced if it exists). Default: standard output.",
)
def generate(model_path: Path, output_path: Path | None) -> None:
    """Write the typed Robot API of the robot model MODEL.rmodel: a Python module with a class
    per device, named after it, with the methods of its kind (effector: write, read,
    set_active; sensor and monitor: read, latest, set_active, listen; command and memory
    command: issue; event and memory event: read, listen, set_active; module: set_active and
    its devices), and a class named after the model with an attribute per device.

    The classes work over any rcmlconf.rsp.api.DeviceAccess, such as the simulacrum: they name
    the devices and fields and type the values; the codec below them is the same for every
    robot. The model is validated first; an invalid one is reported as `validate` reports it,
    on standard error. The module is the same text for the same model; it passes
    `mypy --strict`, `ruff check` and, with names of up to 50 characters,
    `ruff format --check`.

    \b
    Exit status: 0 written; 1 invalid model, or two devices (or two fields)
      whose names become the same Python name; 2 usage error, unreadable model
      or unwritable FILE.

    \b
    Example:
      rcmlconf rsp generate rcmlconf/reference/robots/cubo/cubo.rmodel -o cubo_api.py
    then, in an application (access: a DeviceAccess, such as the simulacrum):
      from cubo_api import Cubo
      cubo = Cubo(access)
      cubo.left_wheel.write(speed=120)          # mm/s, in every DOWNLINK from now on
      where = cubo.position.read(timeout=1.0)   # the next value: where.x, where.heading
      cubo.service_button.listen(print)         # each press, from the middleware's thread
      cubo.ir_fire.issue(code=0x20DF)           # an occurrence; returns its ID
    """
    output = Output()
    # Standard output carries the module: what is said about the model goes to standard error.
    messages = Output(stdout=sys.stderr)
    model = load_or_exit(messages, _COMMAND, model_path, load_robot_model)
    try:
        text = generate_module(model, model_path.as_posix())
    except NameClash as exc:
        messages.problem(_COMMAND, f"{model_path}: {exc}")
        sys.exit(1)
    if output_path is None:
        output.out.file.write(text)  # the module exactly as -o writes it, not lines for a terminal
        return
    try:
        output_path.write_text(text, encoding="utf-8")
    except OSError as exc:
        messages.problem(_COMMAND, f"cannot write {output_path}: {exc.strerror or exc}")
        sys.exit(2)
    devices = plural(len(model.devices), "device")
    messages.summary(f"wrote {output_path}: the Robot API of {model.name} ({devices})", ok=True)
