"""`validate --format sarif`: the findings as a SARIF 2.1.0 log (OASIS), the format GitHub code
scanning uploads (github/codeql-action/upload-sarif) and editors' SARIF viewers read.

One run; each rule a requirement of specs/ (its text the rule's description, its level the
finding's: a MUST broken is an error, a SHOULD a warning); each result located by the file's
path as given (relative paths stay relative, as code scanning wants them: to the repository's
root when run from there) and the line and column, from 1."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import PurePath, PurePosixPath
from typing import Any
from urllib.parse import quote

from rcmlconf import __version__
from rcmlconf.diagnostics import Diagnostic
from rcmlconf.specs import Requirement
from rcmlconf.validate.validator import FileReport
from rcmlconf.wording import shorten

SCHEMA_URI = "https://json.schemastore.org/sarif-2.1.0.json"
#: Where a rule's requirement is written: specs/ of the repository README links.
_SPECS = "specs/"
#: What `validate` calls standard input: no file a viewer can open.
_STDIN = "<stdin>"


def to_sarif(
    reports: Sequence[FileReport], requirements: Mapping[str, Requirement]
) -> dict[str, Any]:
    """The SARIF log of a validation run."""
    found = [d for r in reports for d in r.diagnostics]
    rules = sorted({d.rule for d in found})
    index = {rule: number for number, rule in enumerate(rules)}
    return {
        "$schema": SCHEMA_URI,
        "version": "2.1.0",
        "runs": [
            {
                "tool": {
                    "driver": {
                        "name": "rcmlconf",
                        "version": __version__,
                        "rules": [_rule(rule, requirements.get(rule)) for rule in rules],
                    }
                },
                "columnKind": "unicodeCodePoints",
                "results": [_result(d, index[d.rule]) for d in found],
            }
        ],
    }


def _rule(rule: str, requirement: Requirement | None) -> dict[str, Any]:
    described: dict[str, Any] = {"id": rule}
    if requirement is not None:
        text = f"{requirement.level}: {requirement.text}"
        described["shortDescription"] = {"text": shorten(text, 200)}
        described["fullDescription"] = {"text": text}
        described["help"] = {"text": f"{rule} of {_SPECS}{requirement.document}"}
        described["defaultConfiguration"] = {
            "level": "error" if requirement.mandatory else "warning"
        }
    return described


def _result(diagnostic: Diagnostic, rule: int) -> dict[str, Any]:
    message = diagnostic.message
    if diagnostic.hint:
        message = f"{message} (hint: {diagnostic.hint})"
    result: dict[str, Any] = {
        "ruleId": diagnostic.rule,
        "ruleIndex": rule,
        "level": diagnostic.severity.value,  # SARIF's levels include "error" and "warning"
        "message": {"text": message},
    }
    if diagnostic.path != _STDIN:
        location: dict[str, Any] = {"artifactLocation": {"uri": _uri(diagnostic.path)}}
        if diagnostic.line >= 1:  # 0: the file as a whole (SARIF's lines start at 1)
            region = {"startLine": diagnostic.line}
            if diagnostic.column >= 1:
                region["startColumn"] = diagnostic.column
            location["region"] = region
        result["locations"] = [{"physicalLocation": location}]
    return result


def _uri(path: str) -> str:
    """A path as a URI: a relative one as a relative reference (`/` between parts, anything
    else a URI cannot hold escaped), an absolute one as a file: URI."""
    pure = PurePosixPath(PurePath(path).as_posix())
    if pure.is_absolute():
        return pure.as_uri()
    return quote(str(pure), safe="/")
