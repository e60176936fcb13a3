"""rcmlconf commands as a user runs them: real processes, ready files, signals, exit statuses."""

from __future__ import annotations

import json
import os
import random
import signal
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from dataclasses import dataclass
from pathlib import Path

from support.report_schemas import assert_run_report_valid

SCRIPT = Path(sys.executable).parent / "rcmlconf"
COMMAND = [str(SCRIPT)] if SCRIPT.exists() else [sys.executable, "-m", "rcmlconf"]
#: Every wait of these tests is bounded by this many seconds.
BOUND = 20.0


@dataclass
class Running:
    process: subprocess.Popen[str]
    ready: dict[str, object]
    ready_file: Path

    @property
    def rctp_port(self) -> int:
        """The RCTP port of a `serve` ready file's `rctp` URL (rctp://host:port/site)."""
        return int(str(self.ready["rctp"]).rsplit(":", 1)[1].split("/")[0])

    def stop(self, sig: signal.Signals = signal.SIGINT) -> tuple[int, str, str]:
        """Send `sig`; the exit status and everything the process printed."""
        self.process.send_signal(sig)
        out, err = self.process.communicate(timeout=BOUND)
        assert "Traceback" not in err, err
        return self.process.returncode, out, err


@contextmanager
def running(tmp_path: Path, *args: str) -> Iterator[Running]:
    """`rcmlconf ARGS --ready-file F`, once F says it listens; killed at the end if still up."""
    ready_file = tmp_path / "ready.json"
    process = subprocess.Popen(
        [*COMMAND, *args, "--ready-file", str(ready_file)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        deadline = time.monotonic() + BOUND
        while not ready_file.exists():
            assert process.poll() is None, process.communicate()
            assert time.monotonic() < deadline, "the command never said it was ready"
            time.sleep(0.02)
        yield Running(process, json.loads(ready_file.read_text()), ready_file)
    finally:
        if process.poll() is None:
            process.kill()
            process.communicate()


def run_command(*args: str) -> subprocess.CompletedProcess[str]:
    reports = [path for path in _run_reports(args) if not path.exists()]
    done = subprocess.run(
        [*COMMAND, *args], capture_output=True, text=True, timeout=BOUND, check=False
    )
    assert "Traceback" not in done.stderr, done.stderr
    # Every --json report a test has `rcmlconf run` write is valid against the schema rcmlconf
    # ships for it (README: "The JSON report").
    for written in (path for path in reports if path.is_file()):
        assert_run_report_valid(json.loads(written.read_text()))
    return done


def _run_reports(args: tuple[str, ...]) -> list[Path]:
    """The --json files of `rcmlconf run ARGS`."""
    if not args or args[0] != "run":
        return []
    named = [args[i + 1] for i, arg in enumerate(args[:-1]) if arg == "--json"]
    named += [arg.removeprefix("--json=") for arg in args if arg.startswith("--json=")]
    return [Path(name) for name in named]


def run_without_stdin(*argv: str) -> subprocess.CompletedProcess[str]:
    """`argv` started with its standard input closed, as a shell's `command <&-`."""
    return subprocess.run(
        argv,
        stdin=subprocess.DEVNULL,
        capture_output=True,
        text=True,
        timeout=BOUND,
        check=False,
        preexec_fn=lambda: os.close(0),  # descriptor 0 is DEVNULL until then
    )


def free_port(kind: socket.SocketKind = socket.SOCK_STREAM) -> int:
    """A port of 127.0.0.1 nothing listens on (free once the probe is closed)."""
    with socket.socket(socket.AF_INET, kind) as probe:
        probe.bind(("127.0.0.1", 0))
        port: int = probe.getsockname()[1]
        return port


def lasting_port() -> int:
    """A port of 127.0.0.1 free for TCP and UDP, below the kernel's ephemeral range.

    For a target that is restarted on its port: between its runs the port is free, and the
    kernel gives a port of the ephemeral range to any socket bound to port 0 or sending
    unbound (the fuzzer's own, other tests'). None is given this one.
    """
    low = int(Path("/proc/sys/net/ipv4/ip_local_port_range").read_text().split()[0])
    for _ in range(200):
        port = random.randrange(min(10000, low // 2), low)
        with socket.socket() as tcp, socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as udp:
            try:
                tcp.bind(("127.0.0.1", port))
                udp.bind(("127.0.0.1", port))
            except OSError:
                continue
            return port
    raise AssertionError("no free port below the ephemeral range")


def free_pair() -> int:
    """A port whose next port is free too: the client role's RCTP and files ports (D-RCTP-29)."""
    for _ in range(50):
        with socket.socket() as first, socket.socket() as second:
            first.bind(("127.0.0.1", 0))
            port: int = first.getsockname()[1]
            with suppress(OSError):
                second.bind(("127.0.0.1", port + 1))
                return port
    raise AssertionError("no free pair of ports")


def wait_listening(port: int, seconds: float = 30.0) -> None:
    """Until something accepts TCP connections on 127.0.0.1:`port` (bounded)."""
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        with suppress(OSError), socket.create_connection(("127.0.0.1", port), 0.5):
            return
        time.sleep(0.05)
    raise AssertionError(f"nothing listened on {port} within {seconds:g} s")


def waited_with_peak(process: subprocess.Popen[str], deadline: float) -> tuple[int | None, int]:
    """The exit status of `process` once it ended, and its peak RSS in bytes: the highest
    VmHWM of /proc/PID/status read while it ran (the high-water mark of its own memory since it
    started its program). None for the status when it was still running at `deadline` (it is
    killed then). Not wait4's ru_maxrss: Linux counts in it the RSS of the process it was forked
    from (a pytest worker of 380 MiB), whatever the command itself took."""
    peak = 0
    status = Path(f"/proc/{process.pid}/status")
    while process.poll() is None:
        with suppress(OSError):  # gone, or a zombie's status, which has no VmHWM
            for line in status.read_text().splitlines():
                if line.startswith("VmHWM:"):
                    peak = max(peak, int(line.split()[1]) * 1024)  # kB
        if time.monotonic() > deadline:
            process.kill()
            process.wait()
            return None, peak
        time.sleep(0.02)
    return process.returncode, peak


@dataclass
class Measured:
    returncode: int
    stdout: str
    stderr: str
    #: The command's peak resident set size, in bytes.
    peak: int
    #: Whether it ended by itself within BOUND (else it was killed).
    ended: bool


def measured(*argv: str) -> Measured:
    """`argv` run to its end (killed past BOUND), with its own peak RSS."""
    with tempfile.TemporaryFile("w+") as out, tempfile.TemporaryFile("w+") as err:
        process = subprocess.Popen(argv, stdout=out, stderr=err, text=True)
        status, peak = waited_with_peak(process, time.monotonic() + BOUND)
        out.seek(0)
        err.seek(0)
        return Measured(process.returncode, out.read(), err.read(), peak, status is not None)
