"""Runs cases and turns every exception into a verdict.

Each case is bounded by its timeout, times --timeout-scale.
Cases that share no state run side by side.
`Case.serial` cases run one after another, in one lane a role, beside the rest.
`Case.exclusive` cases run last, with nothing else in flight.
"""

from __future__ import annotations

import asyncio
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

from rcmlconf.conformance.context import Context
from rcmlconf.conformance.giveup import BASIC, GIVEN_UP, GiveUp
from rcmlconf.conformance.loopwatch import LoopWatch
from rcmlconf.conformance.probes.lost import Contact, stop
from rcmlconf.conformance.registry import Case
from rcmlconf.conformance.roles import Role
from rcmlconf.conformance.run_defaults import CONNECT_TIMEOUT, SESSION_WAIT
from rcmlconf.conformance.targets import Target
from rcmlconf.conformance.transcript import Address, Entry
from rcmlconf.conformance.verdicts import CaseStop, Failed, Result, Verdict
from rcmlconf.impair.spec import Impairment
from rcmlconf.pcap.writer import Gap, write_pcap

#: The start of the reason of a pass that could not check all of its requirement.
PARTLY = "checked in part; not checked: "


@dataclass(frozen=True, slots=True, kw_only=True)
class RunOptions:
    """How the runner runs the cases. Give every field by name."""

    #: --timeout-scale: multiplies every case's timeout.
    timeout_scale: float = 1.0
    #: --seed: seeds every impairment.
    seed: int = 0
    #: --concurrency: how many cases are in flight at once.
    concurrency: int = 16
    #: --repeat: how many times each case runs.
    repeat: int = 1
    #: --impair: the impairment of every UDP flow of a case that declares none of its own.
    impair: Impairment | None = None
    #: --capture: the directory where a pcap of each case's traffic goes.
    capture: Path | None = None
    #: --session-wait: the longest session timeout (D-RCTP-11) that the cases wait out.
    session_wait: float = SESSION_WAIT
    #: --connect-timeout: how long a client case waits for its client to connect. The case's
    #: own clock starts after that.
    connect_timeout: float = CONNECT_TIMEOUT


def under_test(case: Case, target: Target) -> bool:
    """Whether the target plays the role that the case tests."""
    if case.role is Role.ROBOT:
        return bool(target.rsp)
    if case.role is Role.CLIENT:
        return target.clients is not None
    if case.role is Role.LOCAL:
        return target.locals is not None
    return target.server is not None


def alone(case: Case, target: Target) -> bool:
    """Whether the case runs in its role's lane, one case after another (`Case.serial`).

    Client cases run side by side when the harness starts the clients itself. Each case then
    has its own URL, so each connection belongs to its case (D-RCTP-31). Local cases run side
    by side when each starts a local system of its own (`LocalListener.side_by_side`).
    """
    if case.role is Role.CLIENT and target.clients is not None and target.clients.starts_clients:
        return False
    if case.role is Role.LOCAL and target.locals is not None and target.locals.side_by_side:
        return False
    return case.serial


def robot_pool(target: Target) -> asyncio.Queue[Address]:
    """A queue of the target's RSP robots. A case takes one from it (`Context.rsp`)."""
    pool: asyncio.Queue[Address] = asyncio.Queue()
    for address in target.rsp:
        pool.put_nowait(address)
    return pool


def needs_robot(case: Case, target: Target) -> bool:
    """Whether the case takes one of the target's RSP robots for itself (`Context.rsp`)."""
    return case.role is Role.ROBOT and bool(target.rsp) and target.rsp_model is not None


async def run_case(
    case: Case,
    target: Target,
    options: RunOptions,
    run: int = 1,
    robots: asyncio.Queue[Address] | None = None,
    watch: LoopWatch | None = None,
    robot: Address | None = None,
    contact: Contact | None = None,
) -> Result:
    """Run one case. Its timeout counts from now.

    `robot` is the RSP robot already taken for the case. A robot serves one session at a time
    (D-RSP-12), so the case may have waited for its turn; that wait is not the case's time.
    Without `robot`, the case takes one from `robots` when it asks.
    `contact` keeps the case's control connections, or its datagrams to the robot (`GiveUp`).
    """
    pool = robots or robot_pool(target)
    ctx = Context(case, target, options.timeout_scale, options.seed, pool, options.impair)
    ctx.contact = contact or ctx.contact
    ctx.loop_watch = watch
    ctx.taken = robot
    ctx.session_wait = options.session_wait
    result = await _judged(case, target, options, run, ctx)
    return replace(result, used=tuple(ctx.transcript.used))


async def _judged(
    case: Case, target: Target, options: RunOptions, run: int, ctx: Context
) -> Result:
    """Run the case in `ctx` and give its verdict. Every exception becomes a verdict."""
    started = time.monotonic()
    try:
        lacks = _lacks(case, target)
        if lacks:
            return _result(case, ctx, started, run, Verdict.NOT_APPLICABLE, lacks)
        try:
            await asyncio.wait_for(case.run(ctx), ctx.timeout)
        except Exception as error:
            # An answer out of place is judged before what it led to. A case that failed
            # the answer for what it said has judged it already (`Outstanding.doubt`).
            ctx.answers_in_place(doubts=not isinstance(error, Failed))
            raise
        finally:
            # Close first: the exchange then holds what closing notes, such as a command's end.
            ctx.close()
        ctx.answers_in_place()
    except Failed as failed:
        return _failure(case, ctx, started, run, failed)
    except CaseStop as stopped:
        return _result(case, ctx, started, run, stopped.verdict, stopped.reason)
    except TimeoutError:
        seconds = ctx.timeout
        return Result(
            case=case.id,
            verdict=Verdict.FAIL,
            duration=time.monotonic() - started,
            reason=f"the case did not finish within {seconds:g} s",
            requirement=case.requirements[0],
            expected=("the exchange finished in time",),
            actual="the target kept the case waiting",
            exchange=_exchange(ctx),
            run=run,
            entries=_entries(ctx),
        )
    except OSError as error:  # no probe caught it: a reset fails, the rest is an error
        judged = stop(error, case.requirements[0])
        if isinstance(judged, Failed):
            return _failure(case, ctx, started, run, judged)
        return _result(case, ctx, started, run, judged.verdict, judged.reason)
    except Exception as error:  # a harness bug: an error verdict, never a traceback
        reason = f"harness fault: {type(error).__name__}: {error}"
        return _result(case, ctx, started, run, Verdict.ERROR, reason)
    finally:
        if options.capture is not None:
            _capture(options.capture, case, run, ctx)
    partly = "; ".join(ctx.unchecked)
    return _result(case, ctx, started, run, Verdict.PASS, partly and f"{PARTLY}{partly}")


def _failure(case: Case, ctx: Context, started: float, run: int, failed: Failed) -> Result:
    """A failure. It is inconclusive when the harness's own holds may explain it."""
    excuse = ctx.excuse()
    return Result(
        case=case.id,
        verdict=Verdict.INCONCLUSIVE if excuse else Verdict.FAIL,
        duration=time.monotonic() - started,
        reason=f"{failed.reason}; but {excuse}" if excuse else failed.reason,
        requirement=failed.requirement,
        expected=failed.expected,
        actual=failed.actual,
        exchange=_exchange(ctx),
        run=run,
        entries=_entries(ctx),
    )


async def _absent(case: Case, target: Target, options: RunOptions, run: int) -> Result | None:
    """Wait for a client or local case's implementation to connect or send its HELLO.

    The case's clock starts after this wait: an implementation slow to start is not slow to
    answer. If none came within --connect-timeout, the case is inconclusive, and its result
    holds the report of the command started for it. Else None.
    """
    started = time.monotonic()
    if case.role is Role.CLIENT and target.clients is not None:
        absent = await target.clients.arrival(case.id, options.connect_timeout)
        report = target.clients.finish(case.id) if absent is not None else []
    elif case.role is Role.LOCAL and target.locals is not None:
        absent = await target.locals.arrival(options.connect_timeout)
        report = target.locals.finish() if absent is not None else []
    else:
        return None
    if absent is None:
        return None
    took = time.monotonic() - started
    why = f"{absent} ({report[0]})" if report else absent
    return Result(
        case=case.id,
        verdict=Verdict.INCONCLUSIVE,
        duration=took,
        reason=why,
        exchange=tuple(report),
        run=run,
    )


def capture_path(directory: Path, case: Case, run: int) -> Path:
    """Where a case's pcap goes, such as `rctp_msg_unknown-method.pcap`. Later runs of
    --repeat add `-run2` and so on before the suffix."""
    stem = case.id.replace("/", "_") + (f"-run{run}" if run > 1 else "")
    return directory / f"{stem}.pcap"


def _capture(directory: Path, case: Case, run: int, ctx: Context) -> None:
    """Write the case's payloads as the transcript kept them.

    The file is pcapng (`.pcapng`) when the transcript left some payloads out. Its blocks then
    say where (rcmlconf.pcap.writer).
    """
    captured = ctx.transcript.capture
    path = capture_path(directory, case, run)
    if any(isinstance(item, Gap) for item in captured):
        path = path.with_suffix(".pcapng")
    try:
        with path.open("wb") as file:
            write_pcap(file, captured)
    except (OSError, ValueError) as error:  # ValueError: an endpoint with a name, not an IP
        ctx.transcript.note(f"capture not written: {error}")


async def run_cases(
    cases: Sequence[Case],
    target: Target,
    options: RunOptions,
    done: Callable[[Result], None] = lambda _: None,
) -> list[Result]:
    """Run every case `options.repeat` times. `done` hears of each result as it comes."""
    results: list[Result] = []
    gate = asyncio.Semaphore(max(1, options.concurrency))
    robots = robot_pool(target)
    watch = LoopWatch()
    dead = {role: GiveUp() for role in GIVEN_UP}  # a target of each role, judged apart

    async def one(case: Case, run: int) -> None:
        # A robot case waits for a free robot before it takes a slot. Its clock starts only
        # then: one robot under test serves the robot cases one after another.
        robot = await robots.get() if needs_robot(case, target) else None
        if case.role is Role.LOCAL and target.locals is not None:
            # A local case starts once the local system under test is done with the case
            # before (D-RSP-24: one session at a time). That wait is not the case's time.
            await target.locals.settled()
        try:
            async with gate:  # a client waiting in line would run out its own timers
                result = await _absent(case, target, options, run) or _dead(case, target, run, dead)
                if result is None:
                    given_up = dead.get(case.role)
                    contact = given_up.begin() if given_up is not None else None
                    result = await run_case(
                        case, target, options, run, robots, watch, robot, contact
                    )
                    if given_up is not None and contact is not None:
                        given_up.ended(contact, result.verdict)
        finally:
            if robot is not None:
                robots.put_nowait(robot)
            if case.role is Role.CLIENT and target.clients is not None:
                target.clients.done(case.id)
        result = replace(result, ended=time.time())
        results.append(result)
        done(result)

    async def lane(serial: list[Case], run: int) -> None:
        for case in serial:
            await one(case, run)

    # Serial cases share state with each other, such as the access privilege or the one
    # client connection. They share none with the rest: one lane a role, beside the others.
    lanes: dict[Role, list[Case]] = {}
    for case in cases:
        if alone(case, target) and not case.exclusive:
            lanes.setdefault(case.role, []).append(case)
    if target.locals is not None:
        target.locals.runs = sum(c.role is Role.LOCAL for c in cases) * options.repeat
    if target.clients is not None:  # D-RCTP-31: the case URLs, in the order they run
        clients = [c for c in cases if c.role is Role.CLIENT]
        served = {c.id: c.served for c in clients if c.served is not None}
        target.clients.plan([c.id for c in clients] * options.repeat, served)
    watch.start()
    try:
        exclusive = [c for c in cases if c.exclusive]
        for run in range(1, options.repeat + 1):
            if run > 1 and exclusive:
                # What the exclusive cases held may count against the server's caps for a
                # second after they closed it (D-RCTP-33).
                await asyncio.sleep(options.timeout_scale)
            # The longest cases first. A case that waits out a protocol timer should not also
            # wait for a free slot: the suite takes at least as long as its slowest case.
            # The BASIC cases go before them, so a dead target fails those before the run
            # gives up.
            free = (c for c in cases if not alone(c, target) and not c.exclusive)
            longest_first = sorted(free, key=lambda c: (c.id not in BASIC, -c.timeout))
            concurrent = [one(c, run) for c in longest_first]
            await asyncio.gather(*concurrent, *(lane(serial, run) for serial in lanes.values()))
            # The exclusive cases run alone. Other cases' connections would count against
            # the caps they check (D-RCTP-32).
            for case in exclusive:
                await one(case, run)
    finally:
        watch.stop()
    order = {c.id: i for i, c in enumerate(cases)}
    return sorted(results, key=lambda r: (r.run, order[r.case]))


def _dead(case: Case, target: Target, run: int, dead: dict[Role, GiveUp]) -> Result | None:
    """The result of a case that applies but is not run, as the run gave up on its role's
    dead target. None when the case runs."""
    given_up = dead.get(case.role)
    if given_up is None or given_up.reason is None or _lacks(case, target):
        return None
    return Result(
        case=case.id, verdict=Verdict.INCONCLUSIVE, duration=0.0, reason=given_up.reason, run=run
    )


def _result(
    case: Case, ctx: Context, started: float, run: int, verdict: Verdict, reason: str
) -> Result:
    took = time.monotonic() - started
    if verdict is Verdict.PASS:
        return Result(case=case.id, verdict=verdict, duration=took, reason=reason, run=run)
    return Result(
        case=case.id,
        verdict=verdict,
        duration=took,
        reason=reason,
        exchange=_exchange(ctx),
        run=run,
        entries=_entries(ctx),
    )


def _exchange(ctx: Context) -> tuple[str, ...]:
    """The exchange's lines as the transcript keeps them: its start and its end."""
    return tuple(ctx.transcript.lines)


def _entries(ctx: Context) -> tuple[Entry, ...]:
    """The exchange as data, as the transcript keeps it."""
    return tuple(ctx.transcript.entries)


def _lacks(case: Case, target: Target) -> str:
    """Why the case does not apply: the target's ICS lacks a feature it needs. Else ""."""
    missing = [f for f in case.features if f not in target.features]
    return "the ICS does not declare " + ", ".join(repr(f) for f in missing) if missing else ""
