"""`rcmlconf validate PATH...`"""

from __future__ import annotations

import gc
import sys
from pathlib import Path

import click

from rcmlconf.cli.console import Output, printable
from rcmlconf.cli.stdin import standard_input
from rcmlconf.markup.failure import MAX_DOCUMENT_BYTES
from rcmlconf.validate.annotations import annotation
from rcmlconf.validate.languages import EXTENSIONS
from rcmlconf.validate.report import summary_line, to_json
from rcmlconf.validate.sarif import to_sarif
from rcmlconf.validate.validator import DEFAULT_MAX_FINDINGS, FileReport, Validator
from rcmlconf.wording import one_of, plural

#: The argument, as click names it in a usage error.
_PATHS = "'PATH...'"


def _parse_map(
    ctx: click.Context, param: click.Parameter, values: tuple[str, ...]
) -> dict[str, Path]:
    mapping = {}
    for value in values:
        href, sep, target = value.partition("=")
        if not sep or not href or not target:
            raise click.BadParameter(f"{value!r} is not HREF=FILE (or PREFIX/=DIR/)")
        mapping[href] = Path(target)
    return mapping


def _expand(paths: tuple[str, ...]) -> list[str]:
    """Files as given, directories as every file below them with a language's extension
    (*.rcml, *.rxid, *.rmodel), in name order."""
    files: list[str] = []
    for name in paths:
        path = Path(name)
        if name != "-" and path.is_dir():
            files.extend(
                str(p) for p in sorted(path.rglob("*")) if p.suffix in EXTENSIONS and p.is_file()
            )
        else:
            files.append(name)
    return files


def _files(paths: tuple[str, ...], allow_empty: bool) -> list[str]:
    """The files to check (`_expand`), or the usage error that says why there is none to."""
    if paths.count("-") > 1:
        raise click.BadParameter("- is given twice: standard input is read once", param_hint=_PATHS)
    files = _expand(paths)
    if not files and not allow_empty:
        # Only directories can hold nothing: a file or - given is always checked.
        patterns = [f"*{extension}" for extension in sorted(EXTENSIONS)]
        # click's message does not go through Output: the names are made printable here.
        where = ", ".join(f"'{printable(path)}'" for path in paths)
        raise click.BadParameter(
            f"nothing to check: no {one_of(patterns)} file below {where}"
            " (--allow-empty accepts that)",
            param_hint=_PATHS,
        )
    return files


@click.command()
@click.argument(
    "paths",
    nargs=-1,
    required=True,
    metavar="PATH...",
    type=click.Path(exists=True, allow_dash=True),
)
@click.option(
    "--format",
    "output_format",
    type=click.Choice(["text", "json", "sarif", "github"]),
    default="text",
    show_default=True,
    help="text: one diagnostic a line; json: one object for the run (its JSON Schema is"
    " report.schema.json in the package's validate/); sarif: a SARIF 2.1.0 log, for GitHub"
    " code scanning (upload-sarif); github: a GitHub Actions workflow command a diagnostic"
    " (::error file=...,line=...::...), which annotates the pull request's lines.",
)
@click.option(
    "--map",
    "session_map",
    multiple=True,
    metavar="HREF=FILE",
    callback=_parse_map,
    help="Check an RXID session whose href is HREF against the local RCML FILE. "
    "An HREF ending in / maps a URL prefix to a directory. Repeatable.",
)
@click.option("--strict", is_flag=True, help="Exit 1 on warnings as well as errors.")
@click.option(
    "--max-findings",
    type=click.IntRange(min=0),
    default=DEFAULT_MAX_FINDINGS,
    show_default=True,
    metavar="N",
    help="Stop checking a file after N findings (0: never). Bounds the time a hostile "
    "document takes; a file cut short is reported invalid.",
)
@click.option(
    "--allow-empty",
    is_flag=True,
    help="Exit 0 when the directories given hold no file to check (else that is a usage error:"
    " a mistyped directory would pass unnoticed).",
)
@click.option("-q", "--quiet", is_flag=True, help="Do not print the summary line on stderr.")
def validate(
    paths: tuple[str, ...],
    output_format: str,
    session_map: dict[str, Path],
    strict: bool,
    max_findings: int,
    allow_empty: bool,
    quiet: bool,
) -> None:
    """Check RCML 2.0 (.rcml), RXID 2.0 (.rxid) and RSP robot model (.rmodel) documents.

    PATH is a file, a directory (every *.rcml, *.rxid and *.rmodel file below it) or - for
    standard input. Every schema and semantic error of a file is reported (up to
    --max-findings), one a line:

    \b
        path:line:col: error|warning: [RULE-ID] message (hint: ...)

    RULE-ID names the requirement of specs/ that is broken. RXID links are checked against
    the RCML each session names: relative *.rcml references beside the RXID file, anything
    else through --map. URLs are never fetched, DTDs never loaded, entities never expanded.

    \b
    Exit status: 0 all valid, 1 any invalid (or any warning with --strict),
    2 usage error (nothing to check, unless --allow-empty) or unreadable file.

    \b
    Examples:
      rcmlconf validate robot.rcml panel.rxid
      rcmlconf validate --format json robots/ > report.json
      rcmlconf validate --format sarif robots/ > rcmlconf.sarif   # GitHub code scanning
      rcmlconf validate --format github robots/                   # in a GitHub Actions step
      rcmlconf validate --map http://cam.example/cam.rcml=cam.rcml panel.rxid
    """
    # A large robot makes a few hundred thousand objects and no reference cycles: the cyclic
    # collector would only rescan them, again and again (a third of the time). The process is
    # short-lived and ours, so it runs without it.
    gc.disable()
    files = _files(paths, allow_empty)
    output = Output()
    validator = Validator(session_map, max_findings)
    reports: list[FileReport] = []
    unreadable = 0
    for name in files:
        try:
            if name == "-":
                # One byte more than a document may hold: enough to tell one too large.
                data = standard_input().read(MAX_DOCUMENT_BYTES + 1)
                report = validator.validate_bytes(data, "<stdin>")
            else:
                report = validator.validate_file(Path(name))
        except OSError as exc:
            output.failure(f"cannot read {name}: {exc.strerror or exc}")
            unreadable += 1
            continue
        reports.append(report)
        if output_format == "text":
            for diagnostic in report.diagnostics:
                output.diagnostic(diagnostic)
        elif output_format == "github":
            output.out.lines([annotation(d) for d in report.diagnostics])
    if output_format == "json":
        output.json(to_json(reports))
    elif output_format == "sarif":
        from rcmlconf.specs import requirements

        output.json(to_sarif(reports, requirements()))
    failed = any(not r.valid or (strict and r.warnings) for r in reports)
    if not quiet:
        cannot = f"; {plural(unreadable, 'file')} could not be read" if unreadable else ""
        output.summary(summary_line(reports) + cannot, ok=not failed and not unreadable)
    sys.exit(2 if unreadable else 1 if failed else 0)
