"""Loading the document a command runs on, reported as `rcmlconf validate` reports it."""

from __future__ import annotations

import sys
from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

from rcmlconf.cli.console import Output
from rcmlconf.diagnostics import Diagnostic
from rcmlconf.validate.report import summary_line
from rcmlconf.validate.validator import InvalidRobot

T = TypeVar("T")


def load_or_exit(
    output: Output,
    command: str,
    path: Path,
    load: Callable[[Path, list[Diagnostic]], T],
) -> T:
    """The valid model of `path`, its warnings printed; else its diagnostics printed and exit 1
    (invalid) or 2 (unreadable)."""
    warnings: list[Diagnostic] = []
    try:
        model = load(path, warnings)
    except InvalidRobot as exc:
        if exc.report is None:  # unreadable
            output.problem(command, str(exc))
            sys.exit(2)
        if exc.report.valid:  # valid, but in another language (an RCML file for a model)
            output.problem(
                command,
                f"{path} is a valid <{exc.report.kind}> document, not the one this command takes",
            )
            sys.exit(1)
        for diagnostic in exc.report.diagnostics:
            output.diagnostic(diagnostic)
        output.summary(summary_line([exc.report]), ok=False)
        sys.exit(1)
    for warning in warnings:  # a valid document may still have something to say
        output.diagnostic(warning)
    return model
