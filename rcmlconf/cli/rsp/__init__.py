"""`rcmlconf rsp COMMAND`: tools over RSP robot models (specs/rsp.md).

A group of its own commands, each imported only when run, as the top-level ones are.
"""

from __future__ import annotations

import click

from rcmlconf.cli import LazyGroup

#: name -> (module, function, one-line help)
COMMANDS = {
    "generate": (
        "rcmlconf.cli.rsp.generate",
        "generate",
        "Write a robot model's typed Robot API (paper Fig. 4).",
    ),
}


class _RspGroup(LazyGroup):
    table = COMMANDS


@click.group(cls=_RspGroup)
def rsp() -> None:
    """Tools over RSP robot models (.rmodel, specs/rsp.md section 1).

    Run `rcmlconf rsp COMMAND --help` for what each command does.
    """
