"""The independent implementations of tests/foreign/ run as a user runs rcmlconf against theirs:
each its own process, reached only through its address, `rcmlconf run` at default settings (a
client started by the harness for each case, `--client-command`, as a client's CI would).

Each implementation is written from specs/ alone and imports nothing of rcmlconf; `--fault NAME`
makes it misbehave in one of its own ways (`--list-faults` prints NAME, requirement, what).
"""

from __future__ import annotations

import contextlib
import json
import os
import shlex
import signal
import subprocess
import sys
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

from support.processes import COMMAND, free_pair, free_port

FOREIGN = Path(__file__).resolve().parents[1] / "foreign"
#: The longest one run of the suite against one implementation may take (seconds).
RUN_BOUND = 300.0


@dataclass(frozen=True)
class Fault:
    name: str
    requirement: str
    what: str


@dataclass(frozen=True)
class Verdicts:
    """One run of the suite: its exit status and each case's verdict and reason."""

    status: int
    results: dict[str, tuple[str, str]]
    err: str

    def having(self, verdict: str) -> dict[str, str]:
        return {case: why for case, (found, why) in self.results.items() if found == verdict}


@dataclass(frozen=True)
class Implementation:
    """One role's independent implementation: how to start it and how the suite reaches it."""

    #: Its folder under tests/foreign/.
    folder: str
    #: `server` or `robot` (it listens; the suite is pointed at it), `client` or `local` (the
    #: suite listens; it is pointed at the suite, and runs again after each case).
    role: str

    @property
    def main(self) -> Path:
        return FOREIGN / self.folder / "main.py"

    def file(self, name: str) -> Path:
        return FOREIGN / self.folder / name

    def faults(self) -> list[Fault]:
        listed = subprocess.run(
            [sys.executable, str(self.main), "--list-faults"],
            capture_output=True,
            text=True,
            timeout=30,
            check=True,
        )
        return [Fault(*line.split("\t", 2)) for line in listed.stdout.splitlines() if line]

    def run_suite(
        self, tmp: Path, faults: Sequence[str] = (), only: Sequence[str] = ()
    ) -> Verdicts:
        """`rcmlconf run` against the implementation made to misbehave in `faults`, the cases of
        its role (or those `only` names), at default settings."""
        report = tmp / f"report-{os.getpid()}-{time.monotonic_ns()}.json"
        chosen = [arg for case in only for arg in ("--only", case)]
        fault_args = [arg for fault in faults for arg in ("--fault", fault)]
        if self.role in ("server", "robot"):
            with self._listening(tmp, fault_args) as address:
                done = _suite([*self._target(address), *chosen, "--json", str(report)])
        elif self.role == "client":
            # Started by the harness once per case (--client-command), as a client author's CI
            # would: its cases then run side by side. The loop over /cases is
            # tests/conformance/test_run_command.py's.
            words = [sys.executable, str(self.main), *fault_args, "--url"]
            command = shlex.join(words) + " {url}"
            listen = ["--role", "client", "--listen", str(free_pair())]
            done = _suite([*listen, "--client-command", command, *chosen, "--json", str(report)])
        else:
            port = free_port()
            local_key, ics = self._keyed(tmp)
            fault_args += local_key
            suite = subprocess.Popen(
                [*COMMAND, "run", *self._listen(port), *ics, *chosen, "--json", str(report)],
                stdout=subprocess.PIPE,
                stderr=subprocess.PIPE,
                text=True,
            )
            with self._connecting(port, fault_args):
                out, err = suite.communicate(timeout=RUN_BOUND)
            done = subprocess.CompletedProcess(suite.args, suite.returncode, out, err)
        results = {}
        if report.exists():
            found = json.loads(report.read_text())["results"]
            results = {r["case"]: (r["verdict"], r.get("reason") or "") for r in found}
        return Verdicts(done.returncode, results, done.stderr)

    # -- the roles -----------------------------------------------------------------------------

    def _keyed(self, tmp: Path) -> tuple[list[str], list[str]]:
        """A local system's pre-shared key, for its encrypted sessions: its option, and the ICS
        that gives the harness (its robot) the same key."""
        key, ics = tmp / "local.key", tmp / "local-ics.toml"
        if not key.exists():
            key.write_text(os.urandom(32).hex() + "\n")
            ics.write_text(f'[rsp]\npsk-file = "{key}"\n')
        return ["--psk-file", str(key)], ["--ics", str(ics)]

    def _target(self, address: tuple[str, int]) -> list[str]:
        where = f"{address[0]}:{address[1]}"
        if self.role == "server":
            return ["--target", where, "--rcml", str(self.file("robot.rcml"))]
        return [
            "--rsp-target",
            where,
            "--model",
            str(self.file("robot.rmodel")),
            "--ics",
            str(self.file("ics.toml")),
        ]

    def _listen(self, port: int) -> list[str]:
        return ["--role", "local", "--listen", str(port), "--model", str(self.file("robot.rmodel"))]

    @contextlib.contextmanager
    def _listening(self, tmp: Path, fault_args: list[str]) -> Iterator[tuple[str, int]]:
        ready = tmp / f"ready-{time.monotonic_ns()}.json"
        extra = ["--psk-file", str(self.file("robot.key"))] if self.role == "robot" else []
        args = [str(self.main), "--port", "0", "--ready-file", str(ready), *extra, *fault_args]
        with _process([sys.executable, *args]) as process:
            deadline = time.monotonic() + 30
            while not ready.exists():
                assert process.poll() is None, f"{self.folder} ended: {process.communicate()}"
                assert time.monotonic() < deadline, f"{self.folder} never said it was ready"
                time.sleep(0.02)
            yield "127.0.0.1", int(json.loads(ready.read_text())["port"])

    @contextlib.contextmanager
    def _connecting(self, port: int, fault_args: list[str]) -> Iterator[None]:
        args = ["--robot", f"127.0.0.1:{port}", "--model", str(self.file("robot.rmodel"))]
        with _process([sys.executable, str(self.main), *args, "--loop", *fault_args]):
            yield


IMPLEMENTATIONS = {
    "rctp_server": Implementation("rctp_server", "server"),
    "rsp_robot": Implementation("rsp_robot", "robot"),
    "rctp_client": Implementation("rctp_client", "client"),
    "rsp_local": Implementation("rsp_local", "local"),
}


def _suite(args: list[str]) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [*COMMAND, "run", *args], capture_output=True, text=True, timeout=RUN_BOUND, check=False
    )


@contextlib.contextmanager
def _process(args: list[str]) -> Iterator[subprocess.Popen[str]]:
    """A process of the implementation, stopped as a user stops it (SIGINT), killed if it hangs."""
    process = subprocess.Popen(
        args, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, start_new_session=True
    )
    try:
        yield process
    finally:
        if process.poll() is None:
            process.send_signal(signal.SIGINT)
            try:
                process.communicate(timeout=10)
            except subprocess.TimeoutExpired:
                process.kill()
                process.communicate()
