"""The reports rcmlconf writes, checked by the tools their readers use: xmlschema against the
JUnit schema of Jenkins' rules (junit.xsd beside this file)."""

from __future__ import annotations

from functools import cache
from pathlib import Path

import xmlschema

HERE = Path(__file__).parent


@cache
def _junit_schema() -> xmlschema.XMLSchema10:
    return xmlschema.XMLSchema10(str(HERE / "junit.xsd"))


def assert_junit_valid(document: bytes | Path) -> None:
    """Raises xmlschema's error, which says where, for a report Jenkins would refuse."""
    source = str(document) if isinstance(document, Path) else document.decode()
    _junit_schema().validate(source)
