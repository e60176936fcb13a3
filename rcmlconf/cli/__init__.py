"""The `rcmlconf` command: a thin click layer over importable modules.

Commands are imported only when run, so `rcmlconf validate` never pays for what `dissect` needs.
"""

from __future__ import annotations

import importlib
import os
import sys
from typing import NoReturn

import click

from rcmlconf import __version__

#: name -> (module, function, one-line help)
COMMANDS = {
    "cases": (
        "rcmlconf.cli.cases",
        "cases",
        "List the conformance cases, and which requirement of specs/ each one checks.",
    ),
    "client": (
        "rcmlconf.cli.client.commands",
        "client",
        "Read, write, stream and watch a robot over RCTP/2.0 (the reference client).",
    ),
    "dissect": (
        "rcmlconf.cli.dissect",
        "dissect",
        "Decode and analyse a pcap/pcapng capture of RCTP/2.0 and RSP: a line a message, then"
        " the analysis.",
    ),
    "local": (
        "rcmlconf.cli.local",
        "local",
        "Drive an RSP robot as the simulacrum: effector values every T, sensors and events.",
    ),
    "robot": (
        "rcmlconf.cli.robot",
        "robot",
        "Run a robot that speaks RSP on UDP (the reference robot; CUBO is simulated).",
    ),
    "rsp": (
        "rcmlconf.cli.rsp",
        "rsp",
        "Tools over RSP robot models: generate a robot's typed Robot API (paper Fig. 4).",
    ),
    "run": (
        "rcmlconf.cli.run",
        "run",
        "Run the conformance cases against an RCTP server or client, an RSP robot or local"
        " system, or the embedded reference.",
    ),
    "serve": (
        "rcmlconf.cli.serve",
        "serve",
        "Serve a robot over RCTP/2.0 and its files over HTTP (the reference server).",
    ),
    "sniff": (
        "rcmlconf.cli.sniff",
        "sniff",
        "Capture RCTP and RSP live and print a line a message (needs root or CAP_NET_RAW).",
    ),
    "validate": (
        "rcmlconf.cli.validate",
        "validate",
        "Check RCML 2.0, RXID 2.0 and RSP robot-model files against specs/.",
    ),
    "wireshark": (
        "rcmlconf.cli.wireshark",
        "wireshark",
        "Write a Wireshark Lua dissector for RCTP/2.0 and RSP (from the codecs' own tables).",
    ),
}


class LazyGroup(click.Group):
    #: The commands of the group, as COMMANDS; a group of subcommands (`rsp`) has its own.
    table: dict[str, tuple[str, str, str]] = COMMANDS

    def list_commands(self, ctx: click.Context) -> list[str]:
        return sorted(self.table)

    def get_command(self, ctx: click.Context, cmd_name: str) -> click.Command | None:
        if cmd_name not in self.table:
            return None
        module, name, _ = self.table[cmd_name]
        command = getattr(importlib.import_module(module), name)
        assert isinstance(command, click.Command)
        return command

    def format_commands(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        rows = [(name, self.table[name][2]) for name in self.list_commands(ctx)]
        with formatter.section("Commands"):
            formatter.write_dl(rows)


@click.group(cls=LazyGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="rcmlconf")
def cli() -> None:
    """Conformance suite and protocol analyser for RCML 2.0, RXID 2.0, RCTP/2.0 and RSP.

    Every finding names the requirement of specs/ it checks (R-RCML-16, R-XML-2, ...).
    Run `rcmlconf COMMAND --help` for what each command does.
    """


def main() -> None:
    """Console entry point: no traceback ever reaches a user."""
    try:
        cli.main(prog_name="rcmlconf")
    except SystemExit as exit_:
        _leave(exit_.code)
    except BrokenPipeError:
        # The reader went away (`rcmlconf ... | head`): not an error of ours.
        _leave(1)
    except Exception as exc:
        if os.environ.get("RCMLCONF_TRACEBACK"):
            raise
        sys.stderr.write(
            f"rcmlconf: internal error: {type(exc).__name__}: {exc}\n"
            "This is a bug in rcmlconf. Set RCMLCONF_TRACEBACK=1 to see where it happened.\n"
        )
        _leave(2)
    _leave(0)


def _leave(code: str | int | None) -> NoReturn:
    """Flush and end the process without freeing every object one by one, as mypy does: a large
    robot leaves a few hundred thousand behind, and freeing them is all the interpreter's
    shutdown would do. Only the console entry point leaves this way, never a library caller."""
    if isinstance(code, str):
        sys.stderr.write(code + "\n")
        code = 1
    try:
        sys.stdout.flush()
        sys.stderr.flush()
    except BrokenPipeError:
        code = code or 1
    os._exit(code or 0)
