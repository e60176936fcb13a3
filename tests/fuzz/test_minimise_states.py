"""The minimiser and the finding file as state machines (hypothesis): whatever case is built up,
its file reads back the case it holds, and its minimisation still fires, comes from the case's
own bytes, and cannot lose another step."""

from __future__ import annotations

import tempfile
from pathlib import Path

from hypothesis import settings
from hypothesis import strategies as st
from hypothesis.stateful import RuleBasedStateMachine, invariant, precondition, rule

from rcmlconf.fuzz.findings import Finding, load_finding
from rcmlconf.fuzz.minimise import minimise
from rcmlconf.fuzz.oracles import Verdict
from rcmlconf.fuzz.steps import Step, TestCase

#: The bytes the oracle of these machines looks for: a case fires when a step holds it whole.
MARK = b"+1"


def fires(case: TestCase) -> bool:
    return any(MARK in step.data for step in case.steps)


def subsequence(small: bytes, big: bytes) -> bool:
    left = iter(big)
    return all(byte in left for byte in small)


class Cases(RuleBasedStateMachine):
    def __init__(self) -> None:
        super().__init__()
        self.steps: list[Step] = []
        self.folder = Path(tempfile.mkdtemp(prefix="fuzz-states-"))

    @rule(
        data=st.binary(max_size=60),
        channel=st.sampled_from(["control", "data"]),
        tagged=st.booleans(),
    )
    def add(self, data: bytes, channel: str, tagged: bool) -> None:
        self.steps.append(Step(channel, data, "bytes", tagged))  # type: ignore[arg-type]

    @rule(at=st.integers(0, 60), before=st.binary(max_size=8))
    def mark(self, at: int, before: bytes) -> None:
        self.steps.append(Step("control", before + MARK + bytes([at]), "content-length"))

    @precondition(lambda self: bool(self.steps))
    @rule(index=st.integers(0, 100))
    def drop(self, index: int) -> None:
        del self.steps[index % len(self.steps)]

    @property
    def case(self) -> TestCase:
        prefix = (Step("control", b"CONNECT / RCTP/2.0\r\nCSeq: 1\r\n\r\n"),)
        return TestCase("session", prefix, tuple(self.steps), ("bytes",))

    @invariant()
    def the_file_reads_back_its_case(self) -> None:
        finding = Finding(
            number=1,
            verdict=Verdict("violation", "R-RCTP-4", "a test"),
            role="server",
            case=self.case,
            original=self.case,
            stable=(3, 3),
            minimised=True,
            at=0.0,
            target={},
        )
        report, _ = finding.write(self.folder)
        read, item = load_finding(report)
        assert read == self.case
        assert item["requirement"] == "R-RCTP-4"

    @invariant()
    def the_minimised_case_fires_and_comes_from_the_case(self) -> None:
        case = self.case
        if not fires(case):
            return
        small = minimise(case, fires)
        assert fires(small)
        assert small.prefix == case.prefix
        assert len(small.steps) == 1  # one marked step is all the oracle needs
        assert any(subsequence(small.steps[0].data, s.data) for s in case.steps)
        assert small.steps[0].data == MARK


Cases.TestCase.settings = settings(max_examples=30, stateful_step_count=12, deadline=None)
TestCases = Cases.TestCase
