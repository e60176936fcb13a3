"""`rcmlconf cases`: the conformance cases, and which requirement each covers."""

from __future__ import annotations

import sys
from collections.abc import Sequence

import click

from rcmlconf.cli.console import Output
from rcmlconf.conformance.coverage import matrix, unknown_requirements
from rcmlconf.conformance.registry import Case, all_cases, select
from rcmlconf.specs import requirements
from rcmlconf.wording import plural


@click.command()
@click.option(
    "--matrix",
    "show_matrix",
    is_flag=True,
    help="Every MUST and SHOULD of specs/ with the cases covering it; the uncovered last.",
)
@click.option("--only", multiple=True, metavar="GLOB", help="Cases whose ID matches.")
@click.option(
    "--format",
    "output_format",
    type=click.Choice(["text", "json"]),
    default="text",
    show_default=True,
)
@click.option(
    "--strict", is_flag=True, help="With --matrix: exit 1 if a MUST has no case and no check."
)
def cases(show_matrix: bool, only: tuple[str, ...], output_format: str, strict: bool) -> None:
    """List the conformance cases (ID, requirements, role, purpose), or with --matrix the
    requirements of specs/ and the cases that check each.

    A requirement on files (an RCML, RXID or robot-model rule) is checked by `rcmlconf
    validate`, not by a case: the matrix says "validate" for it.

    \b
    Examples:
      rcmlconf cases --only 'rsp/*'
      rcmlconf cases --matrix --strict
      rcmlconf cases --matrix --format json > coverage.json
    """
    output = Output()
    chosen = select(all_cases().values(), only)
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
                    }
                    for c in chosen
                ]
            )
        else:
            list_cases(output, chosen)
        sys.exit(1 if unknown else 0)
    rows = matrix(chosen, texts)
    uncovered = [r for r in rows if not r.covered]
    if output_format == "json":
        output.json(
            [
                {
                    "requirement": r.requirement.id,
                    "level": r.requirement.level,
                    "document": r.requirement.document,
                    "cases": list(r.cases),
                    "validate": r.by_validator,
                }
                for r in rows
            ]
        )
    else:
        for row in sorted(rows, key=lambda r: not r.covered):
            covering = ", ".join(row.cases) or ("validate" if row.by_validator else "UNCOVERED")
            style = "" if row.covered else "bold red"
            output.out.line(
                [
                    (f"{row.requirement.id:<12}", "bold"),
                    (f"{row.requirement.level:<11}", "cyan"),
                    (covering, style),
                ]
            )
    must = [r for r in uncovered if r.requirement.mandatory]
    output.summary(
        f"{len(rows)} requirements: {len(rows) - len(uncovered)} covered, "
        f"{len(uncovered)} uncovered ({len(must)} of them MUST)",
        not uncovered,
    )
    sys.exit(1 if unknown or (strict and must) else 0)


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
