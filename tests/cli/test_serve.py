"""`rcmlconf serve` as a user runs it: a real process, real ports, Ctrl-C, exit statuses."""

from __future__ import annotations

import signal
import socket
import subprocess
import urllib.request
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest
from support.processes import BOUND, Running, run_command, running
from support.robots import CAMERA, ROVER, robot
from support.servers import run

from rcmlconf.reference.client.adapter import Client
from rcmlconf.reference.client.session import Closed, ServerRequest

INVALID = Path(__file__).parents[2] / "vectors" / "xml" / "invalid"


class Serving(Running):
    @property
    def url(self) -> str:
        return str(self.ready["rctp"])


@contextmanager
def serving(tmp_path: Path, rcml: Path, *args: str, http: bool = True) -> Iterator[Serving]:
    """`rcmlconf serve` on free ports, once its ready file says it listens."""
    ports = ["--port", "0", *(["--http-port", "0"] if http else ["--no-http"])]
    with running(tmp_path, "serve", *ports, *args, str(rcml)) as started:
        yield Serving(started.process, started.ready, started.ready_file)


def run_serve(*args: str) -> subprocess.CompletedProcess[str]:
    return run_command("serve", *args)


def test_serves_until_ctrl_c_then_says_bye_to_every_session(tmp_path: Path) -> None:
    with serving(tmp_path, CAMERA) as server:

        @run
        async def session() -> None:
            client = await Client.connect(server.url, robot(CAMERA))
            lens = await client.read("/status/lens")
            assert lens["model"] == "rcmlconf PTZ-1 (simulated)"
            server.process.send_signal(signal.SIGINT)
            bye = await client.next_event(timeout=BOUND)
            assert bye == ServerRequest("BYE", "*", 200, reason="shutdown")
            assert isinstance(await client.next_event(timeout=BOUND), Closed)

        session()
        _, err = server.process.communicate(timeout=BOUND)
        assert server.process.returncode == 0, err
        assert "Traceback" not in err
        assert "stopping: BYE to 1 session" in err
        assert not server.ready_file.exists()


def test_the_banner_and_the_ready_file_say_where_everything_is(tmp_path: Path) -> None:
    with serving(tmp_path, ROVER) as server:
        assert server.url.startswith("rctp://127.0.0.1:")
        assert server.url.endswith("/rover")
        assert isinstance(server.ready["data_port"], int)
        index = urllib.request.urlopen(str(server.ready["http"]), timeout=BOUND).read()
        assert b"rover.rcml" in index
        status, out, err = server.stop(signal.SIGTERM)
    assert status == 0
    assert out == ""
    data = f"UDP port {server.ready['data_port']}"
    for words in ("Rover", "rover driver", server.url, data, f"{server.ready['http']}rover.rxid"):
        assert words in err


def test_port_0_serves_the_files_at_the_port_after_the_one_picked(tmp_path: Path) -> None:
    """Where a client given only the RCTP URL looks (D-RCTP-29); they were on port 1 (0 + 1),
    and the ready file said http://127.0.0.1:1/."""
    with running(tmp_path, "serve", "--port", "0", str(ROVER)) as server:
        rctp = server.rctp_port
        assert server.ready["http"] == f"http://127.0.0.1:{rctp + 1}/"
        index = urllib.request.urlopen(str(server.ready["http"]), timeout=BOUND).read()
        assert b"rover.rcml" in index
        done = run_command("client", f"rctp://127.0.0.1:{rctp}/rover", "read", "/drive/settings")
        status, _, err = server.stop()
    assert (status, done.returncode) == (0, 0), done.stderr
    assert f"http://127.0.0.1:{rctp + 1}/rover.rcml" in err


def test_no_http_serves_no_files(tmp_path: Path) -> None:
    with serving(tmp_path, ROVER, http=False) as server:
        assert server.ready["http"] is None
        status, _, err = server.stop()
    assert status == 0
    assert "http://" not in err


def test_verbose_prints_a_line_per_request(tmp_path: Path) -> None:
    with serving(tmp_path, CAMERA, "-v") as server:

        @run
        async def session() -> None:
            async with await Client.connect(server.url, robot(CAMERA)) as client:
                await client.read("/status/lens")

        session()
        status, out, _ = server.stop()
    assert status == 0
    lines = out.splitlines()
    assert any(line.endswith("READ /status/lens -> 200") for line in lines), out
    assert any("CONNECT /camera -> 200" in line for line in lines), out


def test_quiet_without_verbose(tmp_path: Path) -> None:
    with serving(tmp_path, CAMERA) as server:

        @run
        async def session() -> None:
            async with await Client.connect(server.url, robot(CAMERA)) as client:
                await client.read("/status/lens")

        session()
        status, out, err = server.stop()
    assert status == 0
    assert out == ""
    assert "READ" not in err


def test_an_invalid_robot_exits_1_with_its_diagnostics() -> None:
    path = INVALID / "rcml-version.rcml"
    done = run_serve("--port", "0", str(path))
    assert done.returncode == 1
    assert done.stdout.startswith(f"{path}:2:7: error: [R-RCML-1]")
    assert "1 file checked: 1 invalid" in done.stderr


def test_an_unreadable_robot_exits_2(tmp_path: Path) -> None:
    done = run_serve("--port", "0", str(tmp_path / "missing.rcml"))
    assert done.returncode == 2
    assert done.stderr.startswith("rcmlconf serve: ")
    assert "missing.rcml: cannot be read" in done.stderr
    assert len(done.stderr.splitlines()) == 1


def test_a_port_in_use_exits_2_with_one_line() -> None:
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        done = run_serve("--port", str(port), "--no-http", str(ROVER))
    assert done.returncode == 2
    assert done.stdout == ""
    assert len(done.stderr.splitlines()) == 1
    assert f"port {port}" in done.stderr
    assert "address already in use" in done.stderr


@pytest.mark.parametrize(
    ("args", "words"),
    [
        (["--no-http", "--http-port", "0", str(ROVER)], "exclude each other"),
        (["--driver", "camera", str(ROVER)], "driver 'camera' cannot drive this robot"),
        (["--driver", "warp", str(ROVER)], "'warp' is not one of"),
        (["--port", "70000", str(ROVER)], "70000"),
    ],
)
def test_usage_errors_exit_2(args: list[str], words: str) -> None:
    done = run_serve(*args)
    assert done.returncode == 2
    assert words in done.stderr


def test_help_teaches() -> None:
    done = run_serve("--help")
    for words in ("ROBOT.rcml", "--ready-file", "Exit status", "Examples", "Ctrl-C"):
        assert words in done.stdout
