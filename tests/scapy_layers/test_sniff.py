"""`rcmlconf sniff`: live capture, and the one line that says why capture cannot start."""

from __future__ import annotations

import ctypes.util
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
    return ctypes.util.find_library("pcap") is not None


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


def _free_udp_port() -> socket.socket:
    """A UDP socket on a free loopback port: the port is the test's own while it is open."""
    bound = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    bound.bind(("127.0.0.1", 0))
    return bound


@pytest.mark.skipif(not _can_capture(), reason="needs the right to capture (root) and libpcap")
def test_live_capture_prints_a_line_per_message_and_stops_at_count() -> None:
    """Hermetic: other tests send RSP on loopback too, so the capture decodes the test's own
    port and lets through nothing else (--filter); a port decoded but not let through shows
    that the filter holds."""
    own, other = _free_udp_port(), _free_udp_port()
    port, elsewhere = own.getsockname()[1], other.getsockname()[1]
    process = subprocess.Popen(
        [
            *COMMAND,
            *("-i", "lo", "--count", "3", "--model", str(CUBO)),
            *("--decode-as", f"rsp={port}", "--decode-as", f"rsp={elsewhere}"),
            *("--filter", f"udp port {port}"),
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        _wait_for_line(process, "capturing on lo")
        sender.sendto(HELLO, ("127.0.0.1", elsewhere))  # decoded, but filtered out
        sender.sendto(HELLO, ("127.0.0.1", port))
        sender.sendto(DOWNLINK, ("127.0.0.1", port))
        deadline = time.monotonic() + BOUND
        while process.poll() is None and time.monotonic() < deadline:
            sender.sendto(HELLO, ("127.0.0.1", port))
            time.sleep(0.1)
        out, err = process.communicate(timeout=BOUND)
    finally:
        for open_socket in (sender, own, other):
            open_socket.close()
        if process.poll() is None:
            process.kill()
            process.communicate()
    assert process.returncode == 0, err
    lines = out.splitlines()
    assert len(lines) == 3
    assert lines[0].endswith(
        f"-> 127.0.0.1:{port} RSP HELLO seq=0 session=0x000000000000 period 20 ms"
    )
    assert f"-> 127.0.0.1:{port} RSP DOWNLINK seq=1042" in lines[1]
    assert "leftWheel" in lines[1]
    assert f"-> 127.0.0.1:{port} RSP HELLO" in lines[2]
    assert "3 messages in" in err
    assert "Traceback" not in err


@pytest.mark.skipif(not _can_capture(), reason="needs the right to capture (root) and libpcap")
def test_ctrl_c_ends_cleanly_with_a_count() -> None:
    own = _free_udp_port()
    port = own.getsockname()[1]
    process = subprocess.Popen(
        [*COMMAND, "-i", "lo", "--decode-as", f"rsp={port}", "--filter", f"udp port {port}"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        _wait_for_line(process, "capturing on lo")
        process.send_signal(signal.SIGINT)  # as Ctrl-C
        out, err = process.communicate(timeout=BOUND)
    finally:
        own.close()
        if process.poll() is None:
            process.kill()
            process.communicate()
    assert process.returncode == 0, err
    assert out == ""
    assert "0 messages in 0 frames" in err
    assert "Traceback" not in err


def test_a_filter_that_does_not_compile_is_a_usage_error() -> None:
    result = CliRunner().invoke(sniff, ["-i", "lo", "--filter", "udp prt 5"])
    assert result.exit_code == 2
    assert "Error: Invalid value for '--filter': 'udp prt 5': " in result.stderr
    assert "Traceback" not in result.output


def test_an_empty_interface_name_is_no_interface() -> None:
    result = CliRunner().invoke(sniff, ["-i", ""])
    assert result.exit_code == 2
    assert result.stderr.startswith("rcmlconf sniff: no interface '' (this machine has ")


def test_without_libpcap_capture_is_one_line_and_exit_2() -> None:
    """libpcap compiles the capture's filter: a machine without it (its ctypes module cannot be
    loaded, as here where the import is refused) is told so, not given a traceback."""
    without = COMMAND[2].replace(
        "import sys;", "import sys; sys.modules['scapy.libs.winpcapy'] = None;"
    )
    done = subprocess.run(
        [sys.executable, "-c", without, "-i", "lo"],
        capture_output=True,
        text=True,
        timeout=BOUND,
        check=False,
    )
    assert done.returncode == 2, done.stderr
    assert done.stderr == (
        "rcmlconf sniff: capture on lo needs libpcap to compile its filter: install it (Debian:"
        " apt-get install libpcap0.8)\n"
    )
    assert done.stdout == ""
