"""What `rcmlconf run` checks of its options beyond their click types, before any case runs and
before anything is sent: the site path, the files it reads (--ics, --baseline, --rcml, --model,
and the --impair spec) and the files and directory it writes (--junit, --json, --html and
--capture).

Each fault is a usage error naming the option and the value, on one line (a file name with a
newline in it is shown with `\\n`), so that a report path in a directory that does not exist is
said at once, not after the whole run has been spent.
"""

from __future__ import annotations

import os
import re
import stat
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any, NoReturn, TypeVar

import click

from rcmlconf.conformance.files import shown
from rcmlconf.diagnostics import Severity
from rcmlconf.errors import RcmlconfError
from rcmlconf.wording import one_line, plural, quoted

if TYPE_CHECKING:  # `rcmlconf run`'s options are declared with this module's helpers: it stays
    # light, as the declaring module does (rcmlconf.cli.run)
    from rcmlconf.cli.console import Output
    from rcmlconf.conformance.registry import Case

T = TypeVar("T")
V = TypeVar("V")
F = TypeVar("F", bound=Callable[..., Any])

#: What a baseline's warning lists of the IDs that name no case, at most.
_LISTED_IDS = 10
#: D-RCTP-3: a site path is the path of an RCTP URL (D-RCML-17), `/` or `/NAME...`, as CONNECT
#: sends it: no white space, control characters, `?` or `#`.
_SITE = re.compile(r"/[^\s?#\x00-\x1f\x7f]*")


def site_option(ctx: click.Context, param: click.Parameter, value: str | None) -> str | None:
    """A click callback: --site as a site path, or a usage error."""
    if value is not None and _SITE.fullmatch(value) is None:
        raise click.BadParameter(
            f"{quoted(value)} is not a site path: / or /NAME, without spaces,"
            " control characters, ? or # (D-RCTP-3)"
        )
    return value


def loaded(option: str, load: Callable[[V], T], value: V) -> T:
    """`load(value)`, the reason it gives for refusing (an RcmlconfError) a usage error naming
    the option."""
    try:
        return load(value)
    except RcmlconfError as error:
        raise click.BadParameter(one_line(str(error)), param_hint=f"'{option}'") from None


def robot_file(option: str, load: Callable[[Path], T], path: Path) -> T:
    """A robot's file (--rcml, --model) as `load` reads it, or a usage error that says its first
    error, where `loaded` would only say that it is not valid."""
    from rcmlconf.validate.validator import InvalidRobot

    try:
        return load(path)
    except InvalidRobot as error:
        found = error.report.diagnostics if error.report is not None else []
        errors = [d for d in found if d.severity is Severity.ERROR]
        why = str(error)
        if errors:
            more = f" (and {plural(len(errors) - 1, 'more error')})" if len(errors) > 1 else ""
            why = f"{errors[0].to_text()}{more}; `rcmlconf validate` lists every finding"
        raise click.BadParameter(one_line(why), param_hint=f"'{option}'") from None


def check_report(path: Path, option: str) -> None:
    """A report file the run will write when it ends: not a directory, in a directory that
    exists and takes files, itself writable if it exists."""
    try:
        there = path.stat()
    except (FileNotFoundError, NotADirectoryError):  # the folder's check says which
        there = None
    except OSError as error:  # a link that loops, a name too long
        _refuse(option, path, f"cannot be written: {error.strerror or error}")
    if there is not None and stat.S_ISDIR(there.st_mode):
        _refuse(option, path, "is a directory: give a file name")
    folder = path.parent
    if not folder.is_dir():
        what = "is not a directory" if folder.exists() else "does not exist"
        _refuse(option, path, f"cannot be written: {shown(folder)} {what}")
    if there is not None and not os.access(path, os.W_OK):
        _refuse(option, path, "cannot be written: permission denied")
    if there is None and not os.access(folder, os.W_OK | os.X_OK):
        _refuse(option, path, f"cannot be made: {shown(folder)} takes no new files")


def check_directory(path: Path, option: str) -> None:
    """A directory the run will write into: one that is there and takes files, or one that can
    be made (its nearest existing parent is a directory that takes files)."""
    existing = path
    try:
        while not existing.exists() and existing != existing.parent:
            existing = existing.parent
        if existing == path and not path.is_dir():
            _refuse(option, path, "is a file, not a directory")
        if not existing.is_dir():
            _refuse(option, path, f"cannot be made: {shown(existing)} is not a directory")
        if not os.access(existing, os.W_OK | os.X_OK):
            _refuse(option, path, f"cannot be written: {shown(existing)} takes no new files")
    except OSError as error:
        _refuse(option, path, f"cannot be made: {error.strerror or error}")


def report_option(name: str, dest: str, what: str) -> Callable[[F], F]:
    """A report file's option (--junit, --json, --html): checked by `check_reports`."""
    return click.option(name, dest, type=click.Path(dir_okay=False, path_type=Path), help=what)


def check_reports(files: Mapping[str, Path | None], capture: Path | None) -> None:
    """What the run will write can be written: said now, not after every case has run.
    `files`: each report option (--junit, ...) to its file, if given."""
    given = [(option, path) for option, path in files.items() if path is not None]
    for option, path in given:
        check_report(path, option)
    for index, (option, path) in enumerate(given):
        for other, again in given[index + 1 :]:
            if _same(path, again):
                raise click.UsageError(f"{option} and {other} name the same file, {shown(path)}")
    if capture is not None:
        check_directory(capture, "--capture")


def warn_unknown(
    output: Output, baseline: Path, known: frozenset[str], registry: dict[str, Case]
) -> None:
    """A baseline's IDs that name no case (renamed since, or misspelt): the run goes on."""
    from rcmlconf.conformance.reports.baseline import unknown_ids

    unknown = unknown_ids(known, registry)
    if not unknown:
        return
    listed = ", ".join(unknown[:_LISTED_IDS]) + (", ..." if len(unknown) > _LISTED_IDS else "")
    verb = "is" if len(unknown) == 1 else "are"
    output.notice(
        f"rcmlconf run: warning: {shown(baseline)} names {plural(len(unknown), 'ID')} that"
        f" {verb} no case: {listed}"
    )


def _same(one: Path, other: Path) -> bool:
    # Not resolve(): a symbolic link that loops would raise; the names are compared as written.
    return os.path.abspath(one) == os.path.abspath(other)


def _refuse(option: str, path: Path, why: str) -> NoReturn:
    raise click.BadParameter(f"{shown(path)} {why}", param_hint=f"'{option}'")
