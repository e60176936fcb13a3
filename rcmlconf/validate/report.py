"""Summaries of a validation run, as data (for `--format json`) and as a sentence.

`report.schema.json` beside this module is the JSON Schema of `--format json`; `version` grows
by one whenever a field changes meaning or goes (a field added keeps it)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from rcmlconf.validate.validator import FileReport
from rcmlconf.wording import plural

#: Version 1: the first with a version (the fields are those of the versionless output).
VERSION = 1
#: The JSON Schema of `--format json`, shipped in the package.
SCHEMA = Path(__file__).with_name("report.schema.json")


def to_json(reports: Sequence[FileReport]) -> dict[str, object]:
    return {
        "version": VERSION,
        "files": [
            {
                "path": r.path,
                "kind": r.kind,
                "valid": r.valid,
                "errors": r.errors,
                "warnings": r.warnings,
                "truncated": r.truncated,
            }
            for r in reports
        ],
        "diagnostics": [d.to_json() for r in reports for d in r.diagnostics],
        "summary": {
            "files": len(reports),
            "valid": sum(r.valid for r in reports),
            "invalid": sum(not r.valid for r in reports),
            "errors": sum(r.errors for r in reports),
            "warnings": sum(r.warnings for r in reports),
        },
    }


def summary_line(reports: Sequence[FileReport]) -> str:
    invalid = sum(not r.valid for r in reports)
    errors = sum(r.errors for r in reports)
    warnings = sum(r.warnings for r in reports)
    counts = ", ".join(
        text
        for n, text in ((errors, plural(errors, "error")), (warnings, plural(warnings, "warning")))
        if n
    )
    cut = sum(r.truncated for r in reports)
    stopped = (
        f"; checking stopped at the limit of findings in {plural(cut, 'file')} "
        "(--max-findings 0 checks everything)"
        if cut
        else ""
    )
    if invalid:
        return f"{plural(len(reports), 'file')} checked: {invalid} invalid ({counts}){stopped}"
    suffix = f" ({counts})" if counts else ""
    return f"{plural(len(reports), 'file')} checked: all valid{suffix}"
