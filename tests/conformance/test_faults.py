"""The harness catches broken implementations: for every fault the reference can be told to make
(`rcmlconf.reference.faults`), some case fails on the embedded reference that makes it, and a
failing case names a requirement the fault breaks.

Each fault gets its own embedded reference on free loopback ports and runs the cases of the role
it breaks (a server fault the server's cases, a robot fault the robot's): first those that check
a requirement the fault breaks, then, if none of them fails, all the others. Several faults run at
once in one loop, a bounded number at a time, the whole bounded in time. `run_faults(...,
every_case=True)` runs every case for every fault, for a full table of what catches what.
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import functools
from collections.abc import AsyncIterator, Iterable

import pytest
from support.robots import TESTBOT, robot
from support.servers import serving

from rcmlconf.conformance.ics import EVERYTHING
from rcmlconf.conformance.registry import Case, all_cases
from rcmlconf.conformance.roles import Role
from rcmlconf.conformance.runner import RunOptions, run_cases
from rcmlconf.conformance.targets import REFERENCE_SESSION_TIMEOUT, Target, embedded_reference
from rcmlconf.conformance.verdicts import Result, Verdict
from rcmlconf.reference.faults import Fault

#: Faults whose embedded references run at once.
CONCURRENT_FAULTS = 8
#: The whole run, at most (seconds).
BOUND = 55.0
#: Faults that only a longer case shows: rsp/session/timeout-bye waits for the robot's 10 s
#: session timeout, which fits its time only with --timeout-scale 2.5.
OPTIONS = {Fault.SILENT_TIMEOUT: RunOptions(timeout_scale=2.5)}
#: Faults of reading values that only a robot with writable bool, string and bytes nodes shows:
#: the embedded reference's rover has none, so its server is the test robot's for them.
TESTBOT_FAULTS = frozenset({Fault.BOOL_NONZERO_TRUE, Fault.STRING_SIZE_UNCHECKED})


def cases_for(fault: Fault) -> list[Case]:
    role = Role.SERVER if fault.implementation == "server" else Role.ROBOT
    return [case for case in all_cases().values() if case.role is role]


async def run_fault(
    fault: Fault, gate: asyncio.Semaphore, every_case: bool = False
) -> list[Result]:
    """The fault's cases on its own embedded reference: those that check a requirement it breaks
    first, and the others only if none of those fails (or `every_case`: all at once)."""
    options = OPTIONS.get(fault, RunOptions())
    cases = cases_for(fault)
    aimed = [case for case in cases if set(case.requirements) & set(fault.requirements)]
    rest = [case for case in cases if case not in aimed]
    async with gate, reference(fault) as target:
        if every_case:
            return await run_cases(cases, target, options)
        results = await run_cases(aimed, target, options)
        if not failures(results):
            results += await run_cases(rest, target, options)
        return results


@contextlib.asynccontextmanager
async def reference(fault: Fault) -> AsyncIterator[Target]:
    """The embedded reference making `fault`; its RCTP server the test robot's for
    `TESTBOT_FAULTS`."""
    async with embedded_reference(EVERYTHING.features, frozenset({fault})) as target:
        if fault not in TESTBOT_FAULTS:
            yield target
            return
        settings = {"faults": frozenset({fault}), "session_timeout": REFERENCE_SESSION_TIMEOUT}
        async with serving(TESTBOT, **settings) as server:
            model = robot(TESTBOT)
            yield dataclasses.replace(
                target, server=("127.0.0.1", server.port), robot=model, site_path=model.site.path
            )


async def run_faults(
    faults: Iterable[Fault], every_case: bool = False
) -> dict[Fault, list[Result]]:
    chosen = list(faults)
    all_cases()  # the case modules imported once, before the references start
    gate = asyncio.Semaphore(CONCURRENT_FAULTS)
    results = await asyncio.gather(*(run_fault(fault, gate, every_case) for fault in chosen))
    return dict(zip(chosen, results, strict=True))


def failures(results: Iterable[Result]) -> list[Result]:
    return [result for result in results if result.verdict is Verdict.FAIL]


def summary(outcomes: dict[Fault, list[Result]]) -> str:
    """A line a fault: the cases that fail with it, and the requirement each names."""
    lines = []
    for fault, results in sorted(outcomes.items(), key=lambda item: item[0].value):
        failed = failures(results)
        caught = ", ".join(f"{r.case} [{r.requirement}]" for r in failed) or "NOTHING"
        errors = [r.case for r in results if r.verdict is Verdict.ERROR]
        also = f" (errors: {', '.join(errors)})" if errors else ""
        lines.append(f"{fault.value} ({', '.join(fault.requirements)}): {caught}{also}")
    return "\n".join(lines)


#: One worker runs both tests, so that every fault's run (24 s) is made once in its process.
pytestmark = pytest.mark.xdist_group("faults")


@functools.cache
def every_fault_run() -> dict[Fault, list[Result]]:
    # Cached for the worker's process, not a module-scoped fixture: pytest-xdist may hand the
    # worker another module's test between the two, and a module fixture is then made again.
    return asyncio.run(asyncio.wait_for(run_faults(Fault), BOUND))


@pytest.fixture
def outcomes() -> dict[Fault, list[Result]]:
    return every_fault_run()


def test_some_case_fails_on_every_fault(outcomes: dict[Fault, list[Result]]) -> None:
    print(summary(outcomes))  # with -s: which cases catch which fault
    uncaught = sorted(f.value for f, results in outcomes.items() if not failures(results))
    assert not uncaught, (
        f"no case catches {len(uncaught)} of {len(outcomes)} faults: {', '.join(uncaught)}\n\n"
        + summary(outcomes)
    )


def test_a_failing_case_names_a_requirement_the_fault_breaks(
    outcomes: dict[Fault, list[Result]],
) -> None:
    misnamed = []
    for fault, results in outcomes.items():
        failed = failures(results)
        if failed and not any(r.requirement in fault.requirements for r in failed):
            named = sorted({str(r.requirement) for r in failed})
            misnamed.append(
                f"{fault.value}: breaks {', '.join(fault.requirements)}; "
                f"the failing cases name {', '.join(named)}"
            )
    assert not misnamed, "\n".join(misnamed) + "\n\n" + summary(outcomes)
