"""`rcmlconf cases`: the conformance cases, and which requirement each covers."""

from __future__ import annotations

import difflib
import sys
from collections.abc import Iterable, Sequence
from pathlib import Path

import click

from rcmlconf.cli.console import Output
from rcmlconf.conformance.coverage import matrix, unknown_requirements
from rcmlconf.conformance.registry import Case, all_cases, select
from rcmlconf.specs import requirements
from rcmlconf.wording import plural, quoted


@click.command()
@click.option(
    "--matrix",
    "show_matrix",
    is_flag=True,
    help="Every MUST and SHOULD of specs/ with the cases covering it; the uncovered last.",
)
@click.option(
    "--only", multiple=True, metavar="GLOB", help="Cases whose ID matches (* ? [seq] [!seq])."
)
@click.option(
    "--format",
    "output_format",
    type=click.Choice(["text", "json"]),
    default="text",
    show_default=True,
)
@click.option(
    "--strict",
    is_flag=True,
    help="With --matrix: exit 1 if a MUST has no case and no check, and specs/ does not say no"
    " case can check it (unobservable).",
)
@click.option(
    "--where",
    metavar="ID",
    help="Print where the case with this ID is written, as path:line, and nothing else.",
)
def cases(
    show_matrix: bool, only: tuple[str, ...], output_format: str, strict: bool, where: str | None
) -> None:
    """List the conformance cases (ID, requirements, role, purpose), or with --matrix the
    requirements of specs/ and the cases that check each, or with --where the source of one.

    A requirement on files (an RCML, RXID or robot-model rule) is checked by `rcmlconf
    validate`, not by a case: the matrix says "validate" for it. One that no black-box case can
    check (what a browser shows) is tagged so in specs/ with the reason, which the matrix shows.

    Each case is written in the module of its area, named after the area's ID: rsp/header/layout
    is in rcmlconf/conformance/cases/rsp_header.py, and rctp/msg/connect in the package
    cases/rctp_msg/ (the big areas are packages, a module a topic). --where prints the file and
    the line its function starts on: its @case, or for the cases a loop registers, the function
    they share. The path is relative to the current directory when below it. An unknown ID exits
    2 and names the IDs nearest to it.

    \b
    Examples:
      rcmlconf cases --only 'rsp/*'
      rcmlconf cases --matrix --strict
      rcmlconf cases --matrix --format json > coverage.json
      rcmlconf cases --where rctp/msg/unknown-method
      code --goto "$(rcmlconf cases --where rsp/local/hello)"
    """
    output = Output()
    if where is not None:
        if show_matrix or only or strict:
            raise click.UsageError("--where takes no --matrix, --only or --strict")
        path, line = case_source(find_case(all_cases(), where))
        if output_format == "json":
            output.json({"id": where, "path": path, "line": line})
        else:
            output.out.line([(f"{path}:{line}", "")])
        sys.exit(0)
    chosen = chosen_cases(all_cases().values(), only)
    texts = requirements()
    unknown = unknown_requirements(chosen, texts)
    for requirement, naming in sorted(unknown.items()):
        output.problem("cases", f"{requirement} is not in specs/ (named by {', '.join(naming)})")
    if not show_matrix:
        if output_format == "json":
            output.json(
                [
                    {
                        "id": c.id,
                        "purpose": c.purpose,
                        "requirements": list(c.requirements),
                        "role": c.role.value,
                        "timeout": c.timeout,
                        "impairment": c.impairment,
                        "features": list(c.features),
                        "serial": c.serial,
                        "exclusive": c.exclusive,
                    }
                    for c in chosen
                ]
            )
        else:
            list_cases(output, chosen)
        sys.exit(1 if unknown else 0)
    rows = matrix(chosen, texts)
    uncovered = [r for r in rows if r.missing]
    unobservable = [r for r in rows if not r.covered and not r.missing]
    if output_format == "json":
        output.json(
            [
                {
                    "requirement": r.requirement.id,
                    "level": r.requirement.level,
                    "document": r.requirement.document,
                    "cases": list(r.cases),
                    "validate": r.by_validator,
                    "unobservable": r.unobservable,
                }
                for r in rows
            ]
        )
    else:
        for row in sorted(rows, key=lambda r: (r.missing, not r.covered)):
            covering = ", ".join(row.cases) or ("validate" if row.by_validator else "UNCOVERED")
            if not row.covered and not row.missing:
                covering = f"unobservable: {row.unobservable}"
            style = "bold red" if row.missing else "" if row.covered else "dim"
            output.out.line(
                [
                    (f"{row.requirement.id:<12}", "bold"),
                    (f"{row.requirement.level:<11}", "cyan"),
                    (covering, style),
                ]
            )
    must = [r for r in uncovered if r.requirement.mandatory]
    covered = len(rows) - len(uncovered) - len(unobservable)
    output.summary(
        f"{len(rows)} requirements: {covered} covered, {len(unobservable)} unobservable by a"
        f" case (specs/ says why), {len(uncovered)} uncovered ({len(must)} of them MUST)",
        not uncovered,
    )
    sys.exit(1 if unknown or (strict and must) else 0)


def chosen_cases(
    found: Iterable[Case], only: Sequence[str], skip: Sequence[str] = ()
) -> list[Case]:
    """The cases --only and --skip choose (`cases` and `run` alike). A glob that is none (`[`
    without `]`: fnmatch would take it as the character, which no ID has) and a choice of no case
    are usage errors, status 2."""
    for option, globs in (("--only", only), ("--skip", skip)):
        for glob in globs:
            problem = glob_problem(glob)
            if problem is not None:
                raise click.BadParameter(
                    f"{quoted(glob)} is not a glob: {problem}",
                    param_hint=f"'{option}'",
                )
    chosen = select(found, only, skip)
    if not chosen:
        given = " ".join(
            f"{o} {quoted(g)}" for o, gs in (("--only", only), ("--skip", skip)) for g in gs
        )
        raise click.UsageError(f"no case matches {given} (`rcmlconf cases` lists them)")
    return chosen


def find_case(found: dict[str, Case], wanted: str) -> Case:
    """The case whose ID is `wanted`. Otherwise a usage error (status 2) that names the IDs
    nearest to it: those ending in it (`unknown-method`), then those spelled alike."""
    if wanted in found:
        return found[wanted]
    ending = [i for i in found if i.endswith(f"/{wanted}")]
    alike = difflib.get_close_matches(wanted, list(found), n=3, cutoff=0.6)
    near = list(dict.fromkeys([*ending, *alike]))
    hint = f"; did you mean {', '.join(near)}?" if near else " (`rcmlconf cases` lists them)"
    raise click.UsageError(f"no case has the ID {quoted(wanted)}{hint}")


def case_source(found: Case) -> tuple[str, int]:
    """The file of `found`'s function, and the line it starts on (its `@case`). The path is
    relative to the current directory when the file is below it."""
    code = found.run.__code__
    path = Path(code.co_filename).resolve()
    try:
        shown = str(path.relative_to(Path.cwd().resolve()))
    except ValueError:
        shown = str(path)
    return shown, code.co_firstlineno


def glob_problem(glob: str) -> str | None:
    """Why `glob` is no glob of fnmatch (a set opened and never closed), or None."""
    at = 0
    while at < len(glob):
        if glob[at] == "[":
            end = at + 1
            end += glob.startswith("!", end)
            end += glob.startswith("]", end)  # `[]]` and `[!]]`: a ] first is in the set
            close = glob.find("]", end)
            if close < 0:
                return f"the [ at character {at + 1} opens a set that no ] closes"
            at = close
        at += 1
    return None


def list_cases(output: Output, chosen: Sequence[Case]) -> None:
    """A line a case: ID, requirements, role, purpose (`cases` and `run --list`)."""
    for c in chosen:
        output.out.line(
            [
                (c.id, "bold"),
                (f"  [{', '.join(c.requirements)}]", "cyan"),
                (f" ({c.role.value}) ", "dim"),
                (c.purpose, ""),
            ]
        )
    output.summary(plural(len(chosen), "case"), True)
