"""An RCTP/2.0 client as the fuzzer sees it (D-FUZZ-8): started for each case on the case URL,
served by the played server until it enters the case's state, sent the steps and the probe,
and judged.

Each case is a new process of `--client-command`, so a crash is the case's own and there is
nothing to restart; `alive` has nothing to probe between cases.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

from rcmlconf.fuzz.client_cases import entries
from rcmlconf.fuzz.client_played import PlayedServer, Seen
from rcmlconf.fuzz.monitor import TargetProcess
from rcmlconf.fuzz.oracles import CRASH, HANG, Verdict, violation
from rcmlconf.fuzz.per_case import StartedOutcome, exit_after_run, run_started, with_url
from rcmlconf.fuzz.rctp_exec import FRAMING_SHARE, Address, Outcome
from rcmlconf.fuzz.rctp_robot import robot_paths
from rcmlconf.fuzz.steps import TestCase
from rcmlconf.rcml.model import RcmlDocument

#: D-RCTP-31: the scenario's run to its last step takes about 5 s (1 s of events, 2.25 s of
#: stream); a client that has not reached a state by three times that will not.
SCENARIO = 15.0
#: Between the steps and the probe: time for the client to take the data stream's steps, which
#: the probe on the control connection could otherwise overtake.
PROBE_DELAY = 0.1
POLL = 0.005
#: The case URL's path: one case runs at a time, so all share it (D-RCTP-31).
CASE_PATH = "/"


@dataclass(slots=True)
class ClientOutcome(StartedOutcome):
    #: The server's requests still unanswered when the case ended, for people.
    owing: list[str] = field(default_factory=list)
    #: The fuzzer closed the connection first (the probe answered, or a message it took amiss).
    we_closed: bool = False
    refused_framing: bool = False


class ClientTarget:
    role = "client"
    fresh = True

    def __init__(
        self,
        rcml: Path,
        robot: RcmlDocument,
        listen: Address,
        command: str,
        *,
        wait: float,
        connect_timeout: float,
    ) -> None:
        self.robot = robot
        self.listen = listen
        self.wait = wait
        self.connect_timeout = connect_timeout
        self.url = f"rctp://{listen[0]}:{listen[1]}{CASE_PATH}"
        self.command = with_url(command, self.url)
        self.entries = entries(robot_paths(robot))
        self.played = PlayedServer(rcml, robot, listen[0], listen[1])

    def run(self, case: TestCase) -> Outcome:
        seen = Seen(case, self.entries[case.state])
        self.played.expect(seen)
        out = ClientOutcome(state=case.state)
        out.ours = {self.listen}
        try:
            run_started(self.command, out, lambda process: self._follow(seen, process, out))
        finally:
            self.played.forget()
        out.payloads = list(seen.payloads)
        out.statuses = list(seen.statuses)
        out.may_end = seen.may_end
        out.refused_framing = seen.refused_framing
        return out

    def _follow(self, seen: Seen, process: TargetProcess, out: ClientOutcome) -> None:
        deadline = time.monotonic() + self.connect_timeout + SCENARIO
        while seen.reached is None and not seen.ended.is_set() and process.exited() is None:
            if time.monotonic() > deadline:
                break
            time.sleep(POLL)
        if seen.reached is None:
            out.missed = f"the client did not reach {seen.case.state}"
            out.exit = process.exited()
            return
        time.sleep(PROBE_DELAY)
        self.played.probe()
        # D-RCTP-31: a client closes within 1 s a connection R-RCTP-8 or R-RCTP-12 has it close.
        seen.ended.wait(self.wait * FRAMING_SHARE if seen.may_end else self.wait)
        if not seen.ended.is_set():
            out.end = "open"
            out.owing = self.played.unanswered(seen)
            out.unanswered = out.owing[0] if out.owing else None
            out.exit = process.exited()
            return
        out.end = "closed" if seen.client_closed else "open"
        out.we_closed = not seen.client_closed
        out.owing = list(seen.unanswered)
        out.exit = exit_after_run(process)

    def judge(self, out: Outcome) -> Verdict | None:
        assert isinstance(out, ClientOutcome)
        if out.missed is not None:
            return None
        exit = out.exit
        owing = f", owing an answer to {out.owing[0]}" if out.owing else ""
        # One bug, one finding (D-FUZZ-6): a process that died is the crash, whatever it owed.
        if exit is not None and exit.status != 0 and out.may_end is None and not out.we_closed:
            text = f"the client's process {exit.text()} in {out.state}, its run not ended{owing}"
            return Verdict(CRASH, "D-RCTP-31", text)
        if out.end == "closed" and out.owing and out.may_end is None:
            text = f"the client closed the connection before answering {out.owing[0]}"
            return Verdict(CRASH, "R-RCTP-24", text)
        if out.end == "open" and out.unanswered is not None and out.may_end is None:
            text = f"no answer to the server's {out.unanswered} within {self.wait:g} s"
            return Verdict(HANG, "R-RCTP-24", text)
        if out.may_end is not None or out.refused_framing:
            return None  # D-FUZZ-8: how it answers what it cannot frame is the client's
        return violation(out.payloads, out.ours, self.robot, self.listen[1])

    def alive(self) -> Verdict | None:
        return None

    def close(self) -> None:
        self.played.close()
