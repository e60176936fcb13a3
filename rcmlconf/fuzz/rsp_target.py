"""An RSP robot as the fuzzer sees it: run a case, judge it, and probe that it lives.

UDP has no close: a crash shows as the process's exit (--target-command) or as the robot's
port refusing datagrams (ICMP port unreachable); a hang as a fresh session's HELLO that no
WELCOME answers within the wait (D-FUZZ-4). A violation is a MUST the dissector finds broken
in a packet the robot sent, the case's traffic read with the robot's model.
"""

from __future__ import annotations

from rcmlconf.fuzz.oracles import CRASH, HANG, Verdict, violation
from rcmlconf.fuzz.rctp_exec import Address, Outcome
from rcmlconf.fuzz.rsp_exec import RspRunner
from rcmlconf.fuzz.steps import TestCase
from rcmlconf.rsp.model import RobotModel


class RspTarget:
    role = "robot"
    fresh = False

    def __init__(self, address: Address, model: RobotModel, wait: float) -> None:
        self.address = address
        self.model = model
        self.wait = wait
        self.runner = RspRunner(address, model, wait=wait)
        self._probe = TestCase("welcomed", (), ())

    def run(self, case: TestCase) -> Outcome:
        return self.runner.run(case)

    def judge(self, out: Outcome) -> Verdict | None:
        if out.end == "refused":
            return Verdict(CRASH, "R-RSP-20", "the robot's port refused datagrams (ICMP)")
        return violation(out.payloads, out.ours, None, self.address[1], model=self.model)

    def alive(self) -> Verdict | None:
        out = self.runner.run(self._probe)
        if out.end == "refused":
            return Verdict(CRASH, "R-RSP-20", "the robot's port refused a new session's HELLO")
        if out.missed == "no WELCOME":
            return Verdict(
                HANG, "R-RSP-20", f"a new session's HELLO got no WELCOME within {self.wait:g} s"
            )
        return None

    def close(self) -> None:
        pass
