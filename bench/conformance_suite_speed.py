"""How long does the whole conformance suite take against the embedded reference? (issue "The
conformance harness": <= 15 s wall; h2spec runs 146 cases in a few seconds)

Anchor, in the same run: the suite's slowest case run alone. Some cases must wait on the
protocol's own clocks (an RSP session times out after 10 s, D-RSP-13; the server waits 5 s for the
answer to its BYE, R-RCTP-23), so no harness can finish sooner than its slowest case: the ratio
wall / anchor is what running everything else costs on top (1.0 is perfect concurrency).

Also shown: the client role alone (issue 17: under 60 s on the reference client), against its
slowest case alone; the sum of the cases' own times (what a harness running one case at a time
would take), how many cases, the verdicts (all must pass here) and whether every case had the
same verdict in every run (the issue: 20 runs in a row, also under impairment).

    python bench/conformance_suite_speed.py [--runs 3]
    python bench/conformance_suite_speed.py --runs 20 --impair loss=2%,reorder=2%,duplicate=1%
"""

from __future__ import annotations

import argparse
import asyncio
import statistics
import time
from collections.abc import Callable

from rcmlconf.conformance.ics import EVERYTHING
from rcmlconf.conformance.registry import Case, all_cases
from rcmlconf.conformance.roles import Role
from rcmlconf.conformance.runner import RunOptions, run_cases, under_test
from rcmlconf.conformance.targets import embedded_reference, quiet_reference_logs
from rcmlconf.conformance.verdicts import Result, Verdict
from rcmlconf.impair.spec import parse_impairment


async def suite(
    options: RunOptions, only: Callable[[Case], bool] = lambda _: True
) -> tuple[float, list[Result]]:
    """Wall seconds from starting the embedded reference to the last verdict of the cases
    `only` picks, and the results."""
    started = time.perf_counter()
    async with embedded_reference(EVERYTHING.features) as target:
        cases = [c for c in all_cases().values() if under_test(c, target) and only(c)]
        results = await run_cases(cases, target, options)
    return time.perf_counter() - started, results


def client_role(options: RunOptions) -> None:
    """Issue 17's figure: the client role alone (the reference client, `rcmlconf client URL
    scenario`, started for each case), goal under 60 s; anchor: its slowest case alone."""
    wall, results = asyncio.run(suite(options, lambda c: c.role is Role.CLIENT))
    slowest = max(results, key=lambda r: r.duration)
    alone, _ = asyncio.run(suite(options, lambda c: c.id == slowest.case))
    passed = sum(r.verdict is Verdict.PASS for r in results)
    print(
        f"client role: {len(results)} cases, {passed} pass, wall {wall:6.2f} s   goal < 60 s:"
        f" {'met' if wall < 60 else 'NOT met'}"
    )
    print(f"  anchor: its slowest case alone ({slowest.case}): {alone:6.2f} s")
    print(f"  ratio wall / anchor: {wall / alone:5.2f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--impair", help="an impairment of every UDP flow (rcmlconf.impair)")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    impairment = parse_impairment(args.impair) if args.impair else None
    quiet_reference_logs()
    options = RunOptions(seed=args.seed, impair=impairment)
    walls, sums = [], []
    slowest: Result | None = None
    counts: dict[str, int] = {}
    verdicts: dict[str, set[str]] = {}
    reasons: list[str] = []
    for run in range(args.runs):
        wall, results = asyncio.run(suite(options))
        walls.append(wall)
        sums.append(sum(r.duration for r in results))
        slowest = max(results, key=lambda r: r.duration)
        for r in results:
            counts[r.verdict.value] = counts.get(r.verdict.value, 0) + 1
            verdicts.setdefault(r.case, set()).add(r.verdict.value)
            if r.verdict not in (Verdict.PASS, Verdict.NOT_APPLICABLE):
                reasons.append(f"run {run + 1}: {r.case}: {r.verdict.value}: {r.reason}")
        print(f"run {run + 1}: {wall:6.2f} s", flush=True)
    assert slowest is not None
    alone, _ = asyncio.run(suite(options, lambda c: c.id == slowest.case))
    wall = statistics.median(walls)
    print(f"{len(all_cases())} cases registered; verdicts over {args.runs} runs: {counts}")
    print(
        f"suite wall (median of {args.runs}): {wall:6.2f} s   goal <= 15 s: "
        f"{'met' if wall <= 15 else 'NOT met'}"
    )
    print(f"anchor: its slowest case alone ({slowest.case}): {alone:6.2f} s")
    print(f"ratio wall / anchor: {wall / alone:5.2f}")
    print(f"sum of the cases' own times (one at a time): {statistics.median(sums):6.1f} s")
    bad = {v: n for v, n in counts.items() if v not in (Verdict.PASS.value, "not applicable")}
    if bad:
        print(f"NOT all passed: {bad}")
    unstable = {case: sorted(found) for case, found in verdicts.items() if len(found) > 1}
    for reason in reasons:
        print(f"  {reason}")
    print(f"same verdict in every run: {'yes' if not unstable else f'NO: {unstable}'}")
    client_role(options)


if __name__ == "__main__":
    main()
