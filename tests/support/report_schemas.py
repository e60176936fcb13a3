"""The reports rcmlconf writes, checked by the tools their readers use: xmlschema against the
JUnit schema of Jenkins' rules (junit.xsd beside this file), jsonschema against the JSON Schemas
rcmlconf ships."""

from __future__ import annotations

import json
from functools import cache
from pathlib import Path
from typing import Any

import jsonschema
import xmlschema

from rcmlconf.conformance.reports import json_report

HERE = Path(__file__).parent


@cache
def _junit_schema() -> xmlschema.XMLSchema10:
    return xmlschema.XMLSchema10(str(HERE / "junit.xsd"))


def assert_junit_valid(document: bytes | Path) -> None:
    """Raises xmlschema's error, which says where, for a report Jenkins would refuse."""
    source = str(document) if isinstance(document, Path) else document.decode()
    _junit_schema().validate(source)


@cache
def _json_validator(schema: Path) -> jsonschema.protocols.Validator:
    document = json.loads(schema.read_text())
    kind = jsonschema.validators.validator_for(document)
    kind.check_schema(document)
    return kind(document, format_checker=kind.FORMAT_CHECKER)


def assert_json_valid(document: Any, schema: Path) -> None:
    """Raises jsonschema's error, which says where, for a document its schema refuses."""
    _json_validator(schema).validate(document)


def assert_run_report_valid(document: Any) -> None:
    assert_json_valid(document, json_report.SCHEMA)
