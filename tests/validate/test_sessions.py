"""D-RXID-3: which session hrefs the validator follows, maps, or leaves alone."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from support.xml_vectors import XML_VECTORS

from rcmlconf.validate import Validator

CAMERA = XML_VECTORS / "valid" / "appendix-a-corrected.rcml"


def panel(href: str, path: str = "/stream/control/pan") -> bytes:
    return (
        f'<rxid version="2.0"><window><session href="{href}"/>'
        f'<text dataPath="{path}"/></window></rxid>'
    ).encode()


def rules(report: object) -> list[tuple[str, str]]:
    return [(d.rule, d.message) for d in report.diagnostics]


@pytest.mark.parametrize(
    ("href", "why"),
    [
        ("http://cam.example/cam.rcml", "URLs are never fetched"),
        ("file:///etc/passwd", "URLs are never fetched"),
        ("/etc/passwd.rcml", "only relative *.rcml references"),
        ("camera.xml", "only relative *.rcml references"),
    ],
)
def test_hrefs_that_are_not_followed(tmp_path: Path, href: str, why: str) -> None:
    report = Validator().validate_bytes(panel(href, "/no/such/node"), "p.rxid", tmp_path)
    ((rule, message),) = rules(report)
    assert rule == "R-RXID-10"
    assert why in message


def test_a_relative_rcml_is_followed_and_its_links_checked(tmp_path: Path) -> None:
    shutil.copy(CAMERA, tmp_path / "cam.rcml")
    good = Validator().validate_bytes(panel("cam.rcml"), "p.rxid", tmp_path)
    bad = Validator().validate_bytes(panel("cam.rcml", "/stream/control/pann"), "p.rxid", tmp_path)
    assert good.diagnostics == ()
    assert [rule for rule, _ in rules(bad)] == ["R-RXID-9"]


def test_standard_input_has_no_directory_to_look_in() -> None:
    report = Validator().validate_bytes(panel("cam.rcml"), "<stdin>")
    assert "standard input" in rules(report)[0][1]


def test_exact_map(tmp_path: Path) -> None:
    validator = Validator({"http://cam.example/cam.rcml": CAMERA})
    bad = validator.validate_bytes(panel("http://cam.example/cam.rcml", "/x"), "p.rxid", tmp_path)
    assert [rule for rule, _ in rules(bad)] == ["R-RXID-9"]


def test_prefix_map(tmp_path: Path) -> None:
    validator = Validator({"http://robots.example/": CAMERA.parent})
    href = "http://robots.example/appendix-a-corrected.rcml"
    assert validator.validate_bytes(panel(href), "p.rxid", tmp_path).diagnostics == ()


def test_a_mapped_file_that_is_missing_breaks_the_session(tmp_path: Path) -> None:
    validator = Validator({"http://cam.example/cam.rcml": tmp_path / "nowhere.rcml"})
    report = validator.validate_bytes(panel("http://cam.example/cam.rcml"), "p.rxid", tmp_path)
    ((rule, message),) = rules(report)
    assert rule == "R-RXID-11"
    assert "does not exist" in message


def test_a_session_naming_a_panel_is_broken(tmp_path: Path) -> None:
    shutil.copy(XML_VECTORS / "valid" / "misnamed-panel.rcml", tmp_path / "panel.rcml")
    shutil.copy(CAMERA, tmp_path / "appendix-a-corrected.rcml")
    report = Validator().validate_bytes(panel("panel.rcml"), "p.rxid", tmp_path)
    ((rule, message),) = rules(report)
    assert rule == "R-RXID-11"
    assert "<rxid> document, not RCML" in message


def test_sessions_that_lead_round_in_a_loop_are_broken_not_followed(tmp_path: Path) -> None:
    for name, other in (("a.rcml", "b.rcml"), ("b.rcml", "a.rcml")):
        (tmp_path / name).write_bytes(panel(other))
    report = Validator().validate_file(tmp_path / "a.rcml")
    assert [d.rule for d in report.diagnostics] == ["R-XML-10", "R-RXID-11"]
    assert "b.rcml is a <rxid> document, not RCML" in report.diagnostics[1].message
    # Checking b checks a on the way, while b is in progress: a's report names the loop, and
    # the same validator gives that report again when asked for a.
    validator = Validator()
    validator.validate_file(tmp_path / "b.rcml")
    again = validator.validate_file(tmp_path / "a.rcml")
    assert "b.rcml leads back to a document being checked" in again.diagnostics[1].message
