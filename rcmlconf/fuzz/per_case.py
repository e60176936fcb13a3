"""What a case saw whose target is a process of its own, started for it (a client's, D-FUZZ-8;
a local system's, D-FUZZ-9): its state, how the process ended, and whether its run may end."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from rcmlconf.fuzz.monitor import Exit
from rcmlconf.fuzz.rctp_exec import Outcome


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
