"""`rcmlconf browse` on bad input: validate's diagnostics and exit 1, one line and exit 2, every
option checked before anything is sent; and with --wait, a robot that comes later (and comes
back) is connected to."""

from __future__ import annotations

import json
import signal
from pathlib import Path

import pytest
from support.browser import serving
from support.processes import BOUND, free_port, run_command, running
from support.robots import CAMERA, ROBOTS
from websockets.sync.client import connect

CAMERA_RXID = str(ROBOTS / "camera" / "camera.rxid")


def test_an_invalid_panel_gets_validate_s_diagnostics_and_exit_1(tmp_path: Path) -> None:
    (tmp_path / "camera.rcml").write_bytes(CAMERA.read_bytes())
    panel = tmp_path / "panel.rxid"
    panel.write_text(
        '<rxid version="2.0"><window><session href="camera.rcml"/>\n'
        '<slider dataPath="/stream/control/pann"/></window></rxid>'
    )
    done = run_command("browse", str(panel))
    assert done.returncode == 1, done.stderr
    assert done.stdout.startswith(f"{panel}:2:9: error: [R-RXID-9] /stream/control/pann is not")
    assert "did you mean /stream/control/pan?" in done.stdout
    assert "1 error" in done.stderr


def test_a_robot_that_is_not_there_is_one_line_and_exit_2() -> None:
    url = f"rctp://127.0.0.1:{free_port()}/camera"
    done = run_command("browse", CAMERA_RXID, "--connect", f"camera.rcml={url}")
    assert done.returncode == 2
    (line,) = done.stderr.splitlines()
    assert line.startswith("rcmlconf browse: the robot of session 'camera.rcml' is not there:")
    assert line.endswith("start its server, give its URL with --connect, or pass --wait")


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (("--timeout", "nan"), "'nan' is not a finite number"),
        (("--timeout", "61"), "0<x<=60"),
        (("--connect", "camera.rcml"), "is not HREF=rctp://HOST:PORT/PATH"),
        (("--connect", "camera.rcml=http://x/"), "is not an RCTP URL"),
        (("--connect", "other.rcml=rctp://127.0.0.1/"), "'other.rcml' is no session href"),
        (("--port", "65536"), "65536 is not in the range"),
    ],
)
def test_bad_options_are_usage_errors(args: tuple[str, ...], message: str) -> None:
    done = run_command("browse", CAMERA_RXID, *args)
    assert done.returncode == 2
    assert message in done.stderr


def test_an_unreadable_panel_is_exit_2(tmp_path: Path) -> None:
    done = run_command("browse", str(tmp_path / "none.rxid"))
    assert (done.returncode, done.stderr.count("\n")) == (2, 1)
    assert "cannot read" in done.stderr


def test_with_wait_the_page_waits_for_the_robot_and_follows_it_back(tmp_path: Path) -> None:
    port = free_port()
    connect_to = f"camera.rcml=rctp://127.0.0.1:{port}/camera"
    with running(tmp_path, "browse", CAMERA_RXID, "--connect", connect_to, "--wait") as browse:
        url = str(browse.ready["url"]).replace("http:", "ws:").replace("/?", "/socket?")
        origin = f"http://127.0.0.1:{browse.ready['port']}"
        with connect(url, origin=origin, open_timeout=BOUND) as page:  # type: ignore[arg-type]

            def next_state() -> str:
                while True:
                    message = json.loads(page.recv(timeout=BOUND))
                    if message["type"] == "state":
                        return str(message["state"])

            assert next_state() == "connecting"
            assert next_state() == "waiting"
            with serving(tmp_path / "serve", CAMERA, "--port", str(port)) as server:
                while (state := next_state()) != "connected":
                    assert state in ("reconnecting", "waiting")
                server.stop(signal.SIGTERM)  # BYE with Reason: shutdown
                assert next_state() == "closed"
            with serving(tmp_path / "again", CAMERA, "--port", str(port)):
                while (state := next_state()) != "connected":
                    assert state in ("reconnecting", "waiting")
        status, _, _ = browse.stop()
    assert status == 0
