"""The browser's documents: an RXID from a file or a URL, the RCML its sessions name downloaded,
and what it refuses to read, located as `validate` locates it."""

from __future__ import annotations

from pathlib import Path

import pytest
from support.http_files import http_files
from support.robots import CAMERA, ROBOTS

from rcmlconf.browse.sources import Invalid, Unreadable, load_sources

CAMERA_RXID = ROBOTS / "camera" / "camera.rxid"
XML = "application/xml"


def panel_beside_camera(tmp_path: Path, text: str) -> Path:
    (tmp_path / "camera.rcml").write_bytes(CAMERA.read_bytes())
    path = tmp_path / "panel.rxid"
    path.write_text(text)
    return path


def rxid(body: str, href: str = "camera.rcml") -> str:
    return f'<rxid version="2.0"><window><session href="{href}"/>{body}</window></rxid>'


def test_a_file_s_sessions_lead_to_the_rcml_beside_it() -> None:
    sources = load_sources(str(CAMERA_RXID), 5.0)
    assert list(sources.robots) == ["camera.rcml"]
    robot = sources.robots["camera.rcml"]
    assert robot.location == str(CAMERA_RXID.parent / "camera.rcml")
    assert robot.model.title == "RCML sample camera"
    assert len(sources.rxid.windows[0].widgets) == 13


def test_a_url_s_sessions_are_downloaded_relative_to_it() -> None:
    files = {
        "/ui/cam.rxid": (CAMERA_RXID.read_bytes(), XML),
        "/ui/camera.rcml": (CAMERA.read_bytes(), XML),
    }
    with http_files(files) as server:
        url = f"http://127.0.0.1:{server.port}/ui/cam.rxid"
        sources = load_sources(url, 5.0)
    assert server.gets == ["/ui/cam.rxid", "/ui/camera.rcml"]
    assert (
        sources.robots["camera.rcml"].location == f"http://127.0.0.1:{server.port}/ui/camera.rcml"
    )


def test_a_data_path_naming_nothing_is_a_located_error(tmp_path: Path) -> None:
    path = panel_beside_camera(tmp_path, rxid('\n<text dataPath="/status/lens/modle"/>'))
    with pytest.raises(Invalid) as raised:
        load_sources(str(path), 5.0)
    (error,) = raised.value.report.diagnostics
    assert (error.line, error.rule) == (2, "R-RXID-9")
    assert "/status/lens/modle is not a node" in error.message
    assert error.hint == "did you mean /status/lens/model?"


@pytest.mark.parametrize(
    "href",
    ["file:///etc/passwd", "/etc/camera.rcml", "camera.txt", "ftp://127.0.0.1/camera.rcml"],
)
def test_a_session_it_will_not_read_is_an_error(tmp_path: Path, href: str) -> None:
    path = panel_beside_camera(tmp_path, rxid('<text dataPath="/status/lens/model"/>', href))
    with pytest.raises(Invalid) as raised:
        load_sources(str(path), 5.0)
    (error,) = raised.value.report.diagnostics
    assert (error.rule, error.severity.value) == ("R-RXID-10", "error")
    assert error.hint == "the browser needs every RCML"


def test_an_invalid_rcml_is_the_session_s_error(tmp_path: Path) -> None:
    path = panel_beside_camera(tmp_path, rxid(""))
    (tmp_path / "camera.rcml").write_text('<rcml version="2.0"/>')
    with pytest.raises(Invalid) as raised:
        load_sources(str(path), 5.0)
    assert [d.rule for d in raised.value.report.diagnostics] == ["R-RXID-11"]


def test_what_cannot_be_had_is_unreadable(tmp_path: Path) -> None:
    with pytest.raises(Unreadable, match=r"cannot read .*missing\.rxid: No such file"):
        load_sources(str(tmp_path / "missing.rxid"), 5.0)
    with http_files({}) as server, pytest.raises(Unreadable, match="404"):
        load_sources(f"http://127.0.0.1:{server.port}/panel.rxid", 5.0)
    with pytest.raises(Unreadable, match="valid <rcml> document, not an RXID panel"):
        load_sources(str(CAMERA), 5.0)
