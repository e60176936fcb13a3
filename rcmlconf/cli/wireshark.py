"""`rcmlconf wireshark [-o FILE] [--model M]`: the Lua dissector of RCTP/2.0 and RSP."""

from __future__ import annotations

import sys
from pathlib import Path

import click

from rcmlconf.cli.console import Output
from rcmlconf.cli.models import load_or_exit
from rcmlconf.validate.validator import load_robot_model
from rcmlconf.wireshark.lua import generate_lua
from rcmlconf.wording import plural

_COMMAND = "wireshark"


@click.command()
@click.option(
    "-o",
    "--output",
    "output_path",
    type=click.Path(dir_okay=False, path_type=Path),
    metavar="FILE",
    help="Write the plugin to FILE (replaced if it exists). Default: standard output.",
)
@click.option(
    "--model",
    "model_path",
    type=click.Path(path_type=Path),
    metavar="MODEL.rmodel",
    help="An RSP robot model: decode the Device Map and every payload's fields with it.",
)
def wireshark(output_path: Path | None, model_path: Path | None) -> None:
    """Write a Wireshark dissector (Lua) for RCTP/2.0 control messages (TCP 7330, reassembled
    across segments, several to a segment), the RCTP/2.0 data stream (UDP 7330: header,
    DATA and FLOW payloads, heartbeat times) and RSP (UDP 7340: header and session bodies;
    with --model, the Device Map and each device's fields).

    The plugin is generated from the tables of rcmlconf's own codecs, so it reads what they
    read: every malformed part gets an expert error naming the requirement of specs/ it
    breaks (filter `rctp.malformed || rctpds.malformed || rcmlrsp.malformed`). Other ports
    are set in Wireshark's preferences (rctp.tcp_ports, rctpds.udp_ports,
    rcmlrsp.udp_ports); heuristics find the protocols on any port. The protocol RSP is
    named `rcmlrsp` (Wireshark has another "rsp"). The file is the same text for the same
    model.

    \b
    Exit status: 0 written; 1 invalid model; 2 usage error, unreadable model
      or unwritable FILE.

    \b
    Examples:
      rcmlconf wireshark -o rcml.lua
      rcmlconf wireshark -o cubo.lua --model rcmlconf/reference/robots/cubo/cubo.rmodel
      tshark -X lua_script:cubo.lua -r run.pcap -Y 'rcmlrsp.type == 4'
      cp rcml.lua ~/.local/lib/wireshark/plugins/    # for Wireshark itself
    """
    # Standard output may carry the plugin: what is said goes to standard error.
    messages = Output(stdout=sys.stderr)
    model = None
    if model_path is not None:
        model = load_or_exit(messages, _COMMAND, model_path, load_robot_model)
    text = generate_lua(model)
    if output_path is None:
        sys.stdout.write(text)
        return
    try:
        output_path.write_text(text, encoding="utf-8")
    except OSError as exc:
        messages.problem(_COMMAND, f"cannot write {output_path}: {exc.strerror or exc}")
        sys.exit(2)
    decoded = (
        f"RSP payloads of {model.name} ({plural(len(model.devices), 'device')})"
        if model is not None
        else "RSP payloads as bytes (no --model)"
    )
    messages.summary(
        f"wrote {output_path}: RCTP/2.0 control and data stream, RSP; {decoded}", ok=True
    )
