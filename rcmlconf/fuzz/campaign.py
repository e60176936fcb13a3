"""A fuzzing campaign: cases drawn where the state map is thin, judged by the oracles, each
finding minimised, re-run and written once (D-FUZZ-1 to D-FUZZ-7).

The campaign is the same for every role; a `Subject` runs a case against its target, judges
it, and probes that the target lives. Under --target-command a `TargetProcess` starts the
target, says when it exits, and restarts it; `LeakWatch` judges its resource use.
"""

from __future__ import annotations

import json
import random
import resource
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

from rcmlconf.fuzz.findings import Finding
from rcmlconf.fuzz.minimise import minimise
from rcmlconf.fuzz.monitor import LeakWatch, TargetNotReady, TargetProcess
from rcmlconf.fuzz.oracles import CRASH, HANG, LEAK, VIOLATION, Verdict
from rcmlconf.fuzz.rctp_exec import Outcome
from rcmlconf.fuzz.statemap import StateMap
from rcmlconf.fuzz.steps import TestCase

#: A liveness probe after this many cases with nothing odd (D-FUZZ-4).
PROBE_EVERY = 20
#: Re-runs of a minimised finding that say whether it is stable (D-FUZZ-6).
RERUNS = 3
#: The most runs minimising one finding takes; a hang costs a wait each, so fewer.
TRIES, HANG_TRIES = 150, 12
#: The corpus's most cases (--max-memory bounds it further).
CORPUS = 2000
#: The most of the budget minimising one finding takes, and at most this many seconds.
MINIMISE_SHARE, MINIMISE_SECONDS = 0.2, 60.0
#: How long a case that looked like a crash or a hang waits to see the process exit.
EXIT_SETTLE = 0.25
#: A resource sample of the target every this many cases (--target-command).
SAMPLE_EVERY = 10
#: The most points of the report's timeline.
TIMELINE = 2000


class _TargetLost(Exception):
    """A restart under --target-command failed: the campaign cannot go on."""


class Subject(Protocol):
    role: str
    #: D-FUZZ-4's bound on an answer, --timeout-scale applied.
    wait: float
    #: Each case starts a target of its own (a client's or local system's process): nothing
    #: an earlier case did carries over to it.
    fresh: bool

    def run(self, case: TestCase) -> Outcome: ...
    def judge(self, out: Outcome) -> Verdict | None: ...
    def alive(self) -> Verdict | None: ...
    def close(self) -> None: ...


class Cases(Protocol):
    @property
    def states(self) -> tuple[str, ...]: ...
    def kinds(self, state: str) -> tuple[str, ...]: ...
    def make(self, state: str, kind: str, rng: random.Random, count: int = 1) -> TestCase: ...


@dataclass(frozen=True, slots=True, kw_only=True)
class Budget:
    seconds: float | None
    cases: int | None
    #: Cases a second at most; None: as fast as the target answers.
    max_rate: float | None
    #: The fuzzer's own memory, MiB: past it the corpus is trimmed.
    max_memory: int


@dataclass(slots=True)
class Stats:
    cases: int = 0
    elapsed: float = 0.0
    findings: int = 0
    fired: int = 0
    restarts: int = 0
    states: int = 0
    #: (seconds, cases, states reached, findings) about once a second, thinned by half past
    #: TIMELINE points: the report's `timeline`, states over time.
    timeline: list[tuple[float, int, int, int]] = field(default_factory=list)

    @property
    def rate(self) -> float:
        return self.cases / self.elapsed if self.elapsed > 0 else 0.0

    def mark(self) -> None:
        self.timeline.append((round(self.elapsed, 2), self.cases, self.states, self.findings))
        if len(self.timeline) > TIMELINE:
            self.timeline = [*self.timeline[:-1:2], self.timeline[-1]]


@dataclass
class Campaign:
    subject: Subject
    cases: Cases
    out: Path
    seed: int
    budget: Budget
    target: dict[str, Any]
    process: TargetProcess | None = None
    leaks: LeakWatch | None = None
    progress: Callable[[Stats], None] = lambda stats: None
    stats: Stats = field(default_factory=Stats)
    findings: dict[tuple[str, str, str, tuple[str, ...]], Finding] = field(default_factory=dict)
    #: (oracle, rule, state, first kind) -> the finding it was minimised into.
    _seen: dict[tuple[str, str, str, str], Finding] = field(default_factory=dict)
    corpus: list[TestCase] = field(default_factory=list)
    stopped: str | None = None
    #: --state and --kind: the states fuzzed, and the kinds of their cases' first steps (all of
    #: them when empty).
    only: tuple[str, ...] = ()
    only_kinds: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        cells = {
            state: tuple(
                k for k in self.cases.kinds(state) if not self.only_kinds or k in self.only_kinds
            )
            for state in self.cases.states
            if not self.only or state in self.only
        }
        self.map = StateMap({state: kinds for state, kinds in cells.items() if kinds})
        self.rng = random.Random(self.seed)
        self._since_probe: list[TestCase] = []
        self._started = time.monotonic()

    # -- the loop --

    def run(self) -> Stats:
        """Fuzz until the budget is spent. A resumed campaign's budget is this run's: its cases
        and seconds count from now, its totals from the first run."""
        started = self._started = time.monotonic()
        before, first = self.stats.elapsed, self.stats.cases
        last_tick = 0.0
        while self.stopped is None and not self._spent(started, first):
            case = self._next_case()
            try:
                self._one(case)
            except _TargetLost as lost:
                self.stopped = str(lost)
            self.stats.elapsed = before + time.monotonic() - started
            self._pace(started, first)
            if self.stats.elapsed - last_tick >= 1.0:
                last_tick = self.stats.elapsed
                self.stats.states = self.map.states_reached
                self.stats.mark()
                self.progress(self.stats)
        if self.stopped is None:
            self._final_probe()
        self._judge_leak()
        self.stats.elapsed = before + time.monotonic() - started
        self.stats.states = self.map.states_reached
        self.stats.mark()
        return self.stats

    def _past_end(self) -> bool:
        seconds = self.budget.seconds
        return seconds is not None and time.monotonic() - self._started >= seconds

    def _spent(self, started: float, first: int) -> bool:
        if self.budget.cases is not None and self.stats.cases - first >= self.budget.cases:
            return True
        return self._past_end()

    def _pace(self, started: float, first: int) -> None:
        rate = self.budget.max_rate
        if rate is None:
            return
        ahead = (self.stats.cases - first) / rate - (time.monotonic() - started)
        if ahead > 0:
            time.sleep(ahead)

    def _next_case(self) -> TestCase:
        rng = self.rng
        if self.corpus and rng.random() < 0.25:
            base = rng.choice(self.corpus)
            extra = self.cases.make(base.state, rng.choice(self.cases.kinds(base.state)), rng)
            steps = (*base.steps, *extra.steps)[-6:]
            return TestCase(base.state, base.prefix, steps, (*base.kinds, *extra.kinds)[-6:])
        state, kind = self.map.pick(rng)
        return self.cases.make(state, kind, rng, rng.choice((1, 1, 2, 3)))

    def _one(self, case: TestCase) -> None:
        if self.process is not None and self.process.exited() is not None:
            self._probe()  # it died after the case before had been judged: find which one
            if self.process.exited() is not None:
                self._restart()
        began = time.monotonic()
        out = self.subject.run(case)
        took = time.monotonic() - began
        self.stats.cases += 1
        kind = case.kinds[0] if case.kinds else "none"
        if self.map.record(case.state, kind, out.missed is None, tuple(out.statuses), took):
            self._keep(case)
        self._since_probe.append(case)
        self._previous = case
        verdict, probed = self._verdict(out)
        before = not self.subject.fresh and (out.missed is not None or probed or not out.statuses)
        if verdict is not None and before and _downed(verdict):
            # Down before this case's prefix was answered, before it answered anything, or
            # found down by the probe: an earlier case may have done it.
            window = list(self._since_probe)
            self._since_probe.clear()
            self._blame(verdict, window)
        elif verdict is not None:
            self._found(case, verdict, out)
            self._since_probe.clear()
        elif len(self._since_probe) >= PROBE_EVERY:
            self._probe()
        if (
            self.process is not None
            and self.leaks is not None
            and self.stats.cases % SAMPLE_EVERY == 0
        ):
            self.leaks.add(self.process.usage())

    def _verdict(self, out: Outcome) -> tuple[Verdict | None, bool]:
        """The oracles on one run: the process's exit first, then the case's own judgement,
        then, when the case ended oddly, a liveness probe; and whether the probe gave it.

        An answer that did not come while the connection stayed open is a violation only if
        the target still answers a new connection: a target that answers nothing hangs (an
        earlier case may have hung it, D-FUZZ-4)."""
        verdict = self.subject.judge(out)
        probed = False
        # D-FUZZ-1: a close that answers the fuzzer's own FIN ("finished") is how a case ends.
        odd = out.end not in ("open", "finished") or out.missed is not None or verdict is not None
        silent = verdict is not None and verdict.oracle == VIOLATION and out.unanswered is not None
        if odd and (verdict is None or silent):
            found = self.subject.alive()
            if found is not None:
                verdict, probed = found, True
        # Any finding may be a crash seen from outside (a close without an answer): give the
        # process a moment to be seen exiting. A case with no finding costs no wait.
        return self._exited(settle=verdict is not None) or verdict, probed

    def _exited(self, settle: bool = False) -> Verdict | None:
        """The process's exit as a crash (--target-command). `settle`: the case looked like
        one, so give a dying process EXIT_SETTLE to be seen exiting, and the crash is pinned on
        this case, not on the next."""
        if self.process is None:
            return None
        exit = self.process.exited()
        deadline = time.monotonic() + EXIT_SETTLE
        while exit is None and settle and time.monotonic() < deadline:
            time.sleep(0.01)
            exit = self.process.exited()
        if exit is None:
            return None
        return Verdict(
            CRASH,
            "R-RCTP-5" if self.subject.role == "server" else "R-RSP-20",
            f"the target's process {exit.text()}",
        )

    def _probe(self) -> None:
        verdict = self._exited() or self.subject.alive()
        window = list(self._since_probe)
        self._since_probe.clear()
        if verdict is not None:
            self._blame(verdict, window)

    def _blame(self, verdict: Verdict, window: list[TestCase]) -> None:
        """A crash or a hang seen after the cases of `window`: the finding is the case that
        brings it about again on a fresh target, the newest first."""
        if not window:
            # It went down with no case since the probe that found it alive (a timer of its
            # own, a signal): the finding keeps the last case run, which may not bring it back.
            if self._previous is None:
                return
            window = [self._previous]
        # The culprit is among the cases since the last probe: the first one that brings it
        # about again on a fresh target is the finding's (without a restart, the last one).
        culprit = window[-1]
        if self.process is not None:
            self._dirty = True  # each candidate runs on a fresh target
            self._minimise_until = time.monotonic() + MINIMISE_SECONDS
            try:
                for candidate in reversed(window):
                    if self._fires(candidate, verdict):
                        culprit = candidate
                        break
            except _TargetLost:
                pass  # it does not come back: `_found` keeps the newest case as seen, and stops
        self._found(culprit, verdict, None)

    def _final_probe(self) -> None:
        if self._since_probe:
            self._probe()

    def _keep(self, case: TestCase) -> None:
        if len(self.corpus) >= CORPUS or self._memory() > self.budget.max_memory:
            if not self.corpus:
                return
            self.corpus.pop(self.rng.randrange(len(self.corpus)))
        self.corpus.append(case)

    @staticmethod
    def _memory() -> int:
        """The fuzzer's own peak RSS, MiB (Linux gives KiB)."""
        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss // 1024

    # -- findings -------------------------------------------------------------------------------

    def _found(self, case: TestCase, verdict: Verdict, out: Outcome | None) -> None:
        self.stats.fired += 1
        first = case.kinds[0] if case.kinds else "none"
        self.map.found(case.state, first)
        early = (verdict.oracle, verdict.rule, case.state, first)
        known = self._seen.get(early)
        if known is not None:
            known.count += 1
            self._recover(verdict)
            return
        output = self._output() or (out.process_output() if out is not None else None)
        can_rerun = (
            self.process is not None
            or self.subject.fresh
            or verdict.oracle not in (CRASH, HANG)
            or (out is not None and self.subject.alive() is None)
        )
        lost: _TargetLost | None = None
        minimised, last, stable = case, out, (0, 0)
        try:
            self._recover(verdict)
            if can_rerun:
                minimised, last, stable = self._rerun(case, verdict)
        except _TargetLost as error:
            # The finding as seen: neither minimised nor re-run. The campaign ends after it.
            lost, can_rerun = error, False
            minimised, last, stable = case, out, (0, 0)
        finding = Finding(
            number=len(self.findings) + 1,
            verdict=verdict,
            role=self.subject.role,
            case=minimised,
            original=case,
            stable=stable,
            minimised=can_rerun,
            at=self.stats.elapsed,
            target=self.target,
            output=output,
            payloads=list(last.payloads) if last is not None else [],
        )
        existing = self.findings.get(finding.key)
        if existing is not None:
            existing.count += 1
            self._seen[early] = existing
        else:
            self.findings[finding.key] = finding
            self._seen[early] = finding
            self.stats.findings = len(self.findings)
            finding.write(self.out)
        if lost is not None:
            raise lost
        if self.process is None and verdict.oracle in (CRASH, HANG) and self.subject.alive():
            self.stopped = "the target no longer answers; give --target-command to restart it"

    def _rerun(
        self, case: TestCase, verdict: Verdict
    ) -> tuple[TestCase, Outcome | None, tuple[int, int]]:
        """Minimise a finding's case and re-run it (D-FUZZ-6): the case kept, its last run and
        how many of its re-runs fired."""
        slow = verdict.oracle == HANG or "no answer" in verdict.text
        tries = HANG_TRIES if slow else TRIES
        share = (self.budget.seconds or MINIMISE_SECONDS / MINIMISE_SHARE) * MINIMISE_SHARE
        self._minimise_until = time.monotonic() + min(share, MINIMISE_SECONDS)
        minimised = minimise(case, lambda c: self._fires_again(c, verdict), tries)
        self._minimise_until += self.subject.wait * RERUNS * 4
        stable = self._stability(minimised, verdict)
        if stable[0] == 0 and minimised != case:
            # The smaller case does not fire again: keep the one that did, if it does.
            whole = self._stability(case, verdict)
            if whole[0] > 0:
                minimised, stable = case, whole
        last = self._last
        if self._dirty:
            self._restart()
        return minimised, last, stable

    def _output(self) -> dict[str, Any] | None:
        if self.process is None:
            return None
        exit = self.process.exited()
        if exit is None:
            return None
        return {"exit": exit.text(), "status": exit.status, "stderr_tail": exit.stderr_tail}

    _last: Outcome | None = None
    #: The last case run, whatever its verdict.
    _previous: TestCase | None = None
    _minimise_until: float = 0.0

    #: The last run brought the target down: restart it before the next (--target-command).
    _dirty: bool = False

    def _fires(self, case: TestCase, verdict: Verdict, *, rerun: bool = False) -> bool:
        """Run `case` on a live target: does the same oracle fire, for the same requirement?
        Past the budget's end, or the minimiser's share of it, no more runs but a re-run's
        (D-FUZZ-6): the finding keeps what it has."""
        late = self._past_end() or time.monotonic() > self._minimise_until
        if late and not rerun:
            return False
        if self._dirty and self.process is not None:
            self._restart()
        out = self.subject.run(case)
        found = self.subject.judge(out)
        if found is None and verdict.oracle in (CRASH, HANG):
            found = self.subject.alive()
        # A crash looked for may come a moment after the case (at the target's next packet).
        settle = found is not None or verdict.oracle == CRASH
        found = self._exited(settle=settle) or found
        self._last = out
        # Without a process to restart (a client started for each case), nothing is left dirty.
        self._dirty = (
            self.process is not None and found is not None and found.oracle in (CRASH, HANG)
        )
        same = found is not None and found.oracle == verdict.oracle
        if same and verdict.oracle not in (CRASH, HANG):
            same = found is not None and found.rule == verdict.rule
        return same

    def _fires_again(self, case: TestCase, verdict: Verdict) -> bool:
        """`_fires`, twice for a crash or a hang: a target brought down by something else (a
        timer of its own, the case before) must not make the minimiser keep a smaller case."""
        if not self._fires(case, verdict):
            return False
        return verdict.oracle not in (CRASH, HANG) or self._fires(case, verdict)

    def _stability(self, case: TestCase, verdict: Verdict) -> tuple[int, int]:
        """Of RERUNS runs of `case`, how many fire. They are made past the budget's end too
        (D-FUZZ-6): a finding found late still says whether it reproduces, and that costs at
        most RERUNS runs of it."""
        fired = sum(self._fires(case, verdict, rerun=True) for _ in range(RERUNS))
        return fired, RERUNS

    def _recover(self, verdict: Verdict) -> None:
        """Restart a target that exited, or that a crash or a hang left (--target-command)."""
        if self.process is None:
            return
        if self.process.exited() is not None or verdict.oracle in (CRASH, HANG) or self._dirty:
            self._restart()

    def _restart(self) -> None:
        """Start the target again. One that does not start ends the campaign (`_TargetLost`):
        the findings so far are kept, and the report says why it stopped."""
        assert self.process is not None
        try:
            self.process.restart()
        except TargetNotReady as error:
            raise _TargetLost(f"the target could not be restarted: {error}") from None
        self._dirty = False
        self.stats.restarts += 1
        if self.leaks is not None:
            self.leaks.reset()

    def _judge_leak(self) -> None:
        if self.leaks is None:
            return
        leak = self.leaks.judge()
        if leak is None:
            return
        verdict = Verdict(LEAK, "D-FUZZ-4", leak.text)
        probe = (
            self.corpus[-1]
            if self.corpus
            else self.cases.make(self.cases.states[0], "cseq", self.rng)
        )
        finding = Finding(
            number=len(self.findings) + 1, verdict=verdict, role=self.subject.role, case=probe,
            original=probe, stable=(0, 0), minimised=False, at=self.stats.elapsed,
            target=self.target,
        )  # fmt: skip
        self.findings[finding.key] = finding
        self.stats.findings = len(self.findings)
        finding.write(self.out)

    # -- resuming -------------------------------------------------------------------------------

    def save(self) -> Path:
        """state.json: the map, the corpus, the findings' keys, the counts; --resume reads it."""
        path = self.out / "state.json"
        item = {
            "schema": "rcmlconf-fuzz-state/1",
            "seed": self.seed,
            "cases": self.stats.cases,
            "elapsed": self.stats.elapsed,
            "map": self.map.to_json(),
            "corpus": [c.to_json() for c in self.corpus],
            "findings": [f.to_json() for f in self.findings.values()],
        }
        path.write_text(json.dumps(item) + "\n", encoding="utf-8")
        return path

    def resume(self, item: dict[str, Any]) -> None:
        self.map.load(item["map"])
        self.corpus = [TestCase.from_json(c) for c in item["corpus"]][-CORPUS:]
        self.stats.cases = int(item["cases"])
        # A resumed campaign draws other cases than the first part did: the seed moves on.
        self.rng = random.Random(f"{self.seed}:{self.stats.cases}")
        for found in item["findings"]:
            verdict = Verdict(found["oracle"], found["requirement"], found["text"])
            case = TestCase.from_json(found["case"])
            finding = Finding(
                number=int(found["number"]), verdict=verdict, role=found["role"], case=case,
                original=TestCase.from_json(found["original"]),
                stable=(found["stable"]["fired"], found["stable"]["runs"]),
                minimised=found["minimised"], at=found["first_seen"], target=found["target"],
                output=found["target_output"], count=int(found["count"]),
            )  # fmt: skip
            self.findings[finding.key] = finding
        self.stats.findings = len(self.findings)


def _downed(verdict: Verdict) -> bool:
    """Whether the verdict says the target may be down (a crash or a hang)."""
    return verdict.oracle in (CRASH, HANG)
