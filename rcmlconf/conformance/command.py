"""`run --client-command 'CMD {url}'`: the implementation under test started by the harness once
per case, as the embedded reference's client is, and stopped by its process group when the case
ends. What it printed last and how it ended go into the case's report: a client that crashed on
start is then one line away from its traceback, not an inconclusive with no why. Each run leads
a session of its own, so `owners` tells which run opened a connection (D-RCTP-31)."""

from __future__ import annotations

import asyncio
import contextlib
import os
import shlex
import signal
from collections import deque
from dataclasses import dataclass, field

from rcmlconf.conformance.owners import Owners

#: Lines of a run's output kept for the report (its last ones), and the length of each, at most.
TAIL_LINES = 20
LINE_CHARS = 300
#: How long a stopped command has, after SIGTERM to its process group, before SIGKILL.
STOP_GRACE = 2.0


class CommandError(ValueError):
    """A --client-command that cannot be run as written."""


def command_words(template: str, url: str) -> list[str]:
    """The command's words, `{url}` in any of them replaced by the case's URL (or the harness's
    address, for a local system). No shell: a word is never read twice."""
    try:
        words = shlex.split(template)
    except ValueError as error:
        raise CommandError(f"{template!r} does not split into words: {error}") from None
    if not words:
        raise CommandError("the command is empty")
    if not any("{url}" in word for word in words):
        raise CommandError(f"{template!r} has no {{url}} for the case's URL")
    return [word.replace("{url}", url) for word in words]


@dataclass
class CommandRun:
    """One start of the command: its words, its process, what it printed last, how it ended."""

    words: list[str]
    pid: int | None = None
    status: int | None = None
    error: str | None = None
    stopped: bool = False
    tail: deque[str] = field(default_factory=lambda: deque(maxlen=TAIL_LINES))

    def report(self) -> list[str]:
        """Lines for the case's report."""
        shown = shlex.join(self.words)
        if self.error is not None:
            return [f"client command {shown}: could not start: {self.error}"]
        if self.status is not None:
            ended = f"exited with status {self.status}"
        elif self.stopped:
            ended = "was stopped at the case's end"
        else:
            ended = "is running"
        lines = [f"client command {shown} (pid {self.pid}) {ended}"]
        if self.tail:
            lines.append(f"its last {len(self.tail)} lines of output:")
            lines += [f"  | {line}" for line in self.tail]
        return lines


class Command:
    """Starts the command for a URL (`__call__`, a listener's summon) and stops what is still
    running when asked (`stop`)."""

    def __init__(self, template: str) -> None:
        command_words(template, "x")  # refused at once, before any case
        self.template = template
        self.runs: dict[str, CommandRun] = {}
        #: Which run holds the other end of a connection: each run's session, by its URL.
        self.owners = Owners()
        self._processes: dict[str, asyncio.subprocess.Process] = {}
        self._killed: list[asyncio.subprocess.Process] = []

    async def __call__(self, url: str) -> None:
        run = CommandRun(command_words(self.template, url))
        self.runs[url] = run
        try:
            process = await asyncio.create_subprocess_exec(
                *run.words,
                stdin=asyncio.subprocess.DEVNULL,
                stdout=asyncio.subprocess.PIPE,
                stderr=asyncio.subprocess.STDOUT,
                start_new_session=True,  # its own process group: stopped with its children
            )
        except OSError as error:
            run.error = error.strerror or str(error)
            return
        run.pid = process.pid
        self._processes[url] = process
        self.owners.started(url, process.pid)
        try:
            assert process.stdout is not None
            while line := await process.stdout.readline():
                run.tail.append(line.decode("utf-8", "replace").rstrip()[:LINE_CHARS])
            run.status = await process.wait()
        finally:
            self._processes.pop(url, None)
            self.owners.ended(process.pid)
            if process.returncode is None:  # cancelled: `close` waits for its end
                _signal(process, signal.SIGKILL)
                self._killed.append(process)

    async def at(self, address: tuple[str, int]) -> None:
        """A local system's start: `{url}` is the address it sends to, `HOST:PORT`."""
        await self(f"{address[0]}:{address[1]}")

    def stop(self, url: str) -> list[str]:
        """Stop the URL's run if it still runs (SIGTERM to its group, SIGKILL after a grace);
        the lines of its report."""
        run = self.runs.get(url)
        if run is None:
            return []
        process = self._processes.get(url)
        if process is not None and process.returncode is None:
            run.stopped = True
            _signal(process, signal.SIGTERM)
            asyncio.get_running_loop().call_later(STOP_GRACE, _signal, process, signal.SIGKILL)
        return run.report()

    async def close(self) -> None:
        """Stop every run still going and wait for each to end (SIGKILL after the grace): none
        outlives the harness."""
        going = [*self._processes.values(), *self._killed]
        for process in going:
            _signal(process, signal.SIGTERM)
        for process in going:
            try:
                await asyncio.wait_for(process.wait(), STOP_GRACE)
            except TimeoutError:
                _signal(process, signal.SIGKILL)
                await process.wait()


def _signal(process: asyncio.subprocess.Process, which: signal.Signals) -> None:
    if process.returncode is None:
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.killpg(process.pid, which)
