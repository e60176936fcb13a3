"""`rcmlconf sniff`: live capture, and the one line that says why capture cannot start."""

from __future__ import annotations

import json
import os
import selectors
import shutil
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest
from click.testing import CliRunner
from support.rsp_models import CUBO

from rcmlconf.cli.sniff import sniff

ROOT = Path(__file__).resolve().parents[2]
VECTORS = json.loads((ROOT / "vectors" / "rsp" / "packets.json").read_text("utf-8"))
HELLO = bytes.fromhex(next(v["hex"] for v in VECTORS["valid"] if v["name"] == "hello"))
DOWNLINK = bytes.fromhex(
    next(v["hex"] for v in VECTORS["valid"] if v["name"] == "downlink-typical")
)
#: The command as a process, before it is registered in rcmlconf.cli.
COMMAND = [
    sys.executable,
    "-c",
    "import sys; from rcmlconf.cli.sniff import sniff; sniff(sys.argv[1:], 'rcmlconf sniff')",
]
BOUND = 20.0
ROOT_USER = hasattr(os, "geteuid") and os.geteuid() == 0


def test_an_interface_that_does_not_exist_is_one_line_and_exit_2() -> None:
    result = CliRunner().invoke(sniff, ["-i", "nope0"])
    assert result.exit_code == 2
    assert "rcmlconf sniff: no interface 'nope0' (this machine has " in result.stderr
    assert len(result.stderr.splitlines()) == 1
    assert "Traceback" not in result.output


def test_a_bad_decode_as_is_a_usage_error() -> None:
    result = CliRunner().invoke(sniff, ["--decode-as", "http=80"])
    assert result.exit_code == 2
    assert "PROTO=PORT" in result.stderr


@pytest.mark.skipif(
    not ROOT_USER or shutil.which("setpriv") is None,
    reason="needs root to take CAP_NET_RAW away, and setpriv",
)
def test_capture_without_permission_is_one_line_and_exit_2() -> None:
    """Root without CAP_NET_RAW: what a user without the right to capture gets."""
    done = subprocess.run(
        ["setpriv", "--bounding-set=-net_raw", "--inh-caps=-net_raw", *COMMAND, "-i", "lo"],
        capture_output=True,
        text=True,
        timeout=BOUND,
        check=False,
    )
    assert done.returncode == 2, done.stderr
    assert done.stderr.startswith("rcmlconf sniff: capture on lo is not permitted: run as root")
    assert len(done.stderr.splitlines()) == 1
    assert done.stdout == ""


def _can_capture() -> bool:
    if not ROOT_USER:
        return False
    try:
        probe = socket.socket(socket.AF_PACKET, socket.SOCK_RAW)
    except (AttributeError, OSError):
        return False
    probe.close()
    return True


def _wait_for_line(process: subprocess.Popen[str], text: str) -> str:
    """The first line of standard error holding `text`."""
    assert process.stderr is not None
    selector = selectors.DefaultSelector()
    selector.register(process.stderr, selectors.EVENT_READ)
    deadline = time.monotonic() + BOUND
    while time.monotonic() < deadline:
        if selector.select(timeout=0.1):
            line = process.stderr.readline()
            assert line, "the command ended before capturing"
            if text in line:
                return line
    raise AssertionError(f"no line with {text!r}")


@pytest.mark.skipif(not _can_capture(), reason="needs the right to capture (root)")
def test_live_capture_prints_a_line_per_message_and_stops_at_count() -> None:
    process = subprocess.Popen(
        [*COMMAND, "-i", "lo", "--count", "3", "--model", str(CUBO)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        _wait_for_line(process, "capturing on lo")
        sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        server = socket.socket()
        server.bind(("127.0.0.1", 0))
        server.listen()
        port = server.getsockname()[1]
        try:
            sender.sendto(HELLO, ("127.0.0.1", 7340))
            sender.sendto(DOWNLINK, ("127.0.0.1", 7340))
            # Not RCTP or RSP: not shown.
            sender.sendto(b"not ours", ("127.0.0.1", 9))
            with socket.create_connection(("127.0.0.1", port)):
                pass
            deadline = time.monotonic() + BOUND
            while process.poll() is None and time.monotonic() < deadline:
                sender.sendto(HELLO, ("127.0.0.1", 7340))
                time.sleep(0.1)
        finally:
            sender.close()
            server.close()
        out, err = process.communicate(timeout=BOUND)
    finally:
        if process.poll() is None:
            process.kill()
            process.communicate()
    assert process.returncode == 0, err
    lines = out.splitlines()
    assert len(lines) == 3
    assert "127.0.0.1:" in lines[0]
    assert lines[0].endswith(
        "-> 127.0.0.1:7340 RSP HELLO seq=0 session=0x000000000000 period 20 ms"
    )
    assert "RSP DOWNLINK seq=1042" in lines[1]
    assert "leftWheel" in lines[1]
    assert "3 messages in" in err
    assert "Traceback" not in err


@pytest.mark.skipif(not _can_capture(), reason="needs the right to capture (root)")
def test_ctrl_c_ends_cleanly_with_a_count() -> None:
    process = subprocess.Popen(
        [*COMMAND, "-i", "lo", "--decode-as", "rsp=7341"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        _wait_for_line(process, "capturing on lo")
        process.send_signal(signal.SIGINT)  # as Ctrl-C
        out, err = process.communicate(timeout=BOUND)
    finally:
        if process.poll() is None:
            process.kill()
            process.communicate()
    assert process.returncode == 0, err
    assert out == ""
    assert "0 messages in" in err
    assert "Traceback" not in err
