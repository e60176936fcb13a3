"""A case whose target is a process of its own, started for it (a client's, D-FUZZ-8; a local
system's, D-FUZZ-9): the command that starts it, its start, stop and exit, and what the case
saw (its state, how the process ended, whether its run may end)."""

from __future__ import annotations

import shlex
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from rcmlconf.fuzz.monitor import Exit, TargetNotReady, TargetProcess
from rcmlconf.fuzz.rctp_exec import Outcome

#: How long a process whose run ended has to exit by itself before it is stopped.
EXIT_GRACE = 1.0
#: The end of its stderr a finding keeps.
KEPT = 4096
_POLL = 0.005


@dataclass(slots=True)
class StartedOutcome(Outcome):
    state: str = ""
    #: How the process ended by itself (None: it ran until the fuzzer stopped it).
    exit: Exit | None = None
    #: Why the target may end its run after what it was sent, or None.
    may_end: str | None = None

    def process_output(self) -> dict[str, Any] | None:
        exit = self.exit
        if exit is None:
            return None
        return {"exit": exit.text(), "status": exit.status, "stderr_tail": exit.stderr_tail}


def with_url(command: str, url: str) -> str:
    """--client-command with `{url}` filled in, word by word: no shell reads it."""
    return shlex.join(word.replace("{url}", url) for word in shlex.split(command))


def run_started(command: str, out: StartedOutcome, follow: Callable[[TargetProcess], None]) -> None:
    """Start the case's process, `follow` it, and stop it; how it ended by itself (if it did)
    goes into `out`, or why it did not start."""
    process = TargetProcess(command, ready=None, kept=KEPT)
    try:
        process.start()
    except TargetNotReady as error:
        out.missed = str(error)
        return
    try:
        follow(process)
    finally:
        exit = process.stop()
    out.exit = out.exit or exit


def exit_after_run(process: TargetProcess) -> Exit | None:
    """How the process ended, given EXIT_GRACE to end by itself once its run is over."""
    ended = time.monotonic() + EXIT_GRACE
    while process.exited() is None and time.monotonic() < ended:
        time.sleep(_POLL)
    return process.exited()
