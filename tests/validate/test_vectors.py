"""Every document of vectors/xml/ produces exactly the diagnostics its .expected file lists."""

from __future__ import annotations

import pytest
from support.xml_vectors import XmlVector, xml_vectors

from rcmlconf.specs import requirements
from rcmlconf.validate import Validator

VECTORS = xml_vectors()


@pytest.mark.parametrize("vector", VECTORS, ids=lambda v: v.id)
def test_vector(vector: XmlVector) -> None:
    report = Validator().validate_file(vector.path)
    found = [(d.line, d.column, d.severity.value, d.rule) for d in report.diagnostics]
    assert found == list(vector.expected), "\n".join(d.to_text() for d in report.diagnostics)
    assert report.valid == vector.valid


@pytest.mark.parametrize("vector", [v for v in VECTORS if not v.valid], ids=lambda v: v.id)
def test_invalid_vectors_show_an_error(vector: XmlVector) -> None:
    assert vector.error_rules, f"{vector.id} is under invalid/ but expects no error"


def test_severity_follows_the_requirement_level() -> None:
    """A broken MUST is an error, a broken SHOULD a warning (specs/README.md)."""
    known = requirements()
    for vector in VECTORS:
        for line, column, severity, rule in vector.expected:
            assert rule in known, f"{vector.id}:{line}:{column}: {rule} is not in specs/"
            expected = "error" if known[rule].mandatory else "warning"
            assert severity == expected, f"{vector.id}:{line}:{column}: {rule} is {severity}"


def test_one_validator_checks_a_shared_rcml_once() -> None:
    """Several panels may name one robot (paper Fig. 3): its report is reused, relabelled."""
    validator = Validator()
    panel = next(v.path for v in VECTORS if v.path.name == "sample.rxid")
    rcml = panel.with_name("appendix-a-corrected.rcml")
    validator.validate_file(panel)
    again = validator.validate_file(rcml, "camera.rcml")
    assert again.path == "camera.rcml"
    assert again.valid


def test_checking_stops_at_the_limit_of_findings() -> None:
    path = next(v.path for v in VECTORS if v.path.name == "rcml-types.rcml")
    full = Validator(max_findings=0).validate_file(path)
    cut = Validator(max_findings=5).validate_file(path)
    assert len(full.diagnostics) == 12
    assert not full.truncated
    assert cut.diagnostics == full.diagnostics[:5]
    assert cut.truncated
    assert not cut.valid


def test_a_document_cut_short_by_warnings_alone_is_not_called_valid() -> None:
    path = next(v.path for v in VECTORS if v.path.name == "empty-access.rcml")
    report = Validator(max_findings=1).validate_file(path)
    assert report.errors == 0
    assert not report.valid
