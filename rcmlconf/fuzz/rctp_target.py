"""An RCTP/2.0 server as the fuzzer sees it: run a case, judge it, and probe that it lives."""

from __future__ import annotations

from rcmlconf.fuzz.oracles import CRASH, HANG, Verdict, judge
from rcmlconf.fuzz.rctp_drafts import Draft
from rcmlconf.fuzz.rctp_exec import Address, Outcome, RctpRunner
from rcmlconf.fuzz.steps import Step, TestCase
from rcmlconf.rcml.model import RcmlDocument


class RctpTarget:
    role = "server"
    fresh = False

    def __init__(self, address: Address, robot: RcmlDocument, site: str, wait: float) -> None:
        self.address = address
        self.robot = robot
        self.wait = wait
        self.runner = RctpRunner(address, wait=wait)
        connect = Draft("CONNECT", site, (("User-Agent", "rcmlconf-fuzz liveness"),))
        self._probe = TestCase("liveness", (Step("control", connect.with_cseq(1).render()),), ())

    def run(self, case: TestCase) -> Outcome:
        return self.runner.run(case)

    def judge(self, out: Outcome) -> Verdict | None:
        return judge(out, self.robot, self.address[1])

    def alive(self) -> Verdict | None:
        """D-FUZZ-4's liveness probe: a new connection's CONNECT answered within the wait."""
        out = self.runner.run(self._probe)
        where = f"{self.address[0]}:{self.address[1]}"
        if out.end == "refused":
            return Verdict(CRASH, "R-RCTP-5", f"{where} refused a new connection afterwards")
        if not out.statuses:
            return Verdict(
                HANG, "R-RCTP-5", f"a new connection's CONNECT got no answer within {self.wait:g} s"
            )
        return None

    def close(self) -> None:
        self.runner.close()
