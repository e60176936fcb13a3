"""The `rcmlconf` command: a thin click layer over importable modules.

Commands are imported only when run, so `rcmlconf validate` never pays for what `dissect` needs.
"""

from __future__ import annotations

import contextlib
import errno
import importlib
import os
import sys
from typing import NoReturn

import click

from rcmlconf import __version__

#: name -> (module, function, one-line help)
COMMANDS = {
    "browse": (
        "rcmlconf.cli.browse",
        "browse",
        "Show an RXID panel in a web browser, linked to its robots (the RCML browser).",
    ),
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
    "fuzz": (
        "rcmlconf.cli.fuzz",
        "fuzz",
        "Fuzz a peer of any role through its states; each finding minimised, replayable.",
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


class _ReaderGone(Exception):
    """Standard output's reader closed the pipe."""


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

    def invoke(self, ctx: click.Context) -> object:
        try:
            return super().invoke(ctx)
        except BrokenPipeError as exc:
            # click would end a closed pipe with status 1; main() makes it 0.
            raise _ReaderGone from exc

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
    except (BrokenPipeError, _ReaderGone):
        # The reader went away (`rcmlconf dissect ... | head`): it had all it wanted, which is
        # not an error of ours or of the input's.
        _leave(0, quiet_stdout=True)
    except OSError as exc:
        if not _is_output_error(exc):
            _internal_error(exc)
        _output_failed(exc)
    except Exception as exc:
        _internal_error(exc)
    _leave(0)


def _is_output_error(exc: OSError) -> bool:
    """An error writing standard output or error (a full disk, `> /dev/full`), which names no
    file: every file rcmlconf opens itself is reported with its name where it is opened."""
    return exc.filename is None and exc.errno in _OUTPUT_ERRNOS


_OUTPUT_ERRNOS = frozenset({errno.ENOSPC, errno.EIO, errno.EDQUOT, errno.EFBIG, errno.EPIPE})


def _output_failed(exc: OSError) -> NoReturn:
    _say(_cannot_write(exc))
    _leave(2, quiet_stdout=True)


def _cannot_write(exc: OSError) -> str:
    return f"rcmlconf: cannot write the output: {exc.strerror or exc}"


def _internal_error(exc: BaseException) -> NoReturn:
    if os.environ.get("RCMLCONF_TRACEBACK"):
        raise exc
    _say(
        f"rcmlconf: internal error: {type(exc).__name__}: {exc}\n"
        "This is a bug in rcmlconf. Set RCMLCONF_TRACEBACK=1 to see where it happened."
    )
    _leave(2)


def _say(line: str) -> None:
    """A last line on standard error, if it can still be written."""
    try:
        sys.stderr.write(line + "\n")
        sys.stderr.flush()
    except OSError:
        pass


def _leave(code: str | int | None, quiet_stdout: bool = False) -> NoReturn:
    """Flush and end the process without freeing every object one by one, as mypy does: a large
    robot leaves a few hundred thousand behind, and freeing them is all the interpreter's
    shutdown would do. Only the console entry point leaves this way, never a library caller.

    What standard output still holds is written now, and a failure to is reported as such (exit
    2), except where the output is already known lost (`quiet_stdout`)."""
    if isinstance(code, str):
        _say(code)
        code = 1
    if not quiet_stdout:
        try:
            sys.stdout.flush()
        except BrokenPipeError:
            pass
        except OSError as exc:
            _say(_cannot_write(exc))
            code = 2
    with contextlib.suppress(OSError):
        sys.stderr.flush()
    if sys.getprofile() is not None or sys.gettrace() is not None:
        # Under a profiler or tracer (`python -m cProfile -o F -m rcmlconf ...`, coverage), the
        # interpreter's shutdown is what writes its results: end the usual way.
        raise SystemExit(code or 0)
    os._exit(code or 0)
