"""`rcmlconf fuzz` run as a user runs it, and its files checked against the JSON Schemas the
package ships beside them."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import jsonschema

import rcmlconf.fuzz
from support.processes import COMMAND

#: Every command of the fuzz tests ends well within this (the budgets are seconds).
BOUND = 120
SCHEMAS = Path(rcmlconf.fuzz.__file__).parent


def valid(document: object, schema: str) -> None:
    """`document` is what the package's JSON Schema `schema` says."""
    rules = json.loads((SCHEMAS / schema).read_text())
    jsonschema.Draft202012Validator(rules).validate(document)


def fuzz(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [*COMMAND, "fuzz", *args], capture_output=True, text=True, timeout=BOUND, check=False
    )
