"""How fast does `rcmlconf fuzz` run test cases against an RCTP/2.0 server? (issue 29)

The embedded reference server runs as a process of its own (`rcmlconf serve`, as `rcmlconf
fuzz` starts it). One seeded list of test cases is made with the fuzzer's own generator, then
run three ways against it, in the same run, rounds interleaved (the machine is shared):

- the floor: a bare socket loop that sends the same bytes (the session's ID filled in, as the
  fuzzer does) and reads what came within the fuzzer's idle wait (10 ms) after each control
  step, with no checks at all;
- the fuzzer's runner: each case run and judged by the oracles (`RctpTarget.run` and `judge`:
  what it owes, the dissector over the case's traffic);
- the whole campaign (`Campaign.run` for the same number of cases: the state map, the corpus,
  the liveness probes).

The cases are of every state but `stop unanswered`, whose prefix waits out the server's receive
timeout (0.3 s): the target's time, which no loop of bytes could share.

Goal: the runner at least 30 % of the floor on RCTP control exchanges.

    python bench/fuzz_speed.py [--cases 400] [--rounds 3] [--json]
"""

from __future__ import annotations

import argparse
import json
import random
import re
import socket
import statistics
import tempfile
import time
from pathlib import Path

from rcmlconf.conformance.targets import REFERENCE_RCML
from rcmlconf.fuzz.campaign import Budget, Campaign
from rcmlconf.fuzz.launch import embedded_command, free_port, started
from rcmlconf.fuzz.rctp_cases import RctpCases
from rcmlconf.fuzz.rctp_drafts import STOP_UNANSWERED
from rcmlconf.fuzz.rctp_exec import IDLE
from rcmlconf.fuzz.rctp_robot import robot_paths
from rcmlconf.fuzz.rctp_target import RctpTarget
from rcmlconf.fuzz.seeds import control_seeds
from rcmlconf.fuzz.steps import SESSION, TestCase
from rcmlconf.validate.validator import load_robot

_SESSION = re.compile(rb"Session: ([^;\r]+)")


def bare_loop(address: tuple[str, int], cases: list[TestCase]) -> float:
    """The floor: the same bytes, one read after each control step, no checks."""
    start = time.perf_counter()
    for case in cases:
        with socket.create_connection(address, timeout=IDLE) as sock:
            session = b"none"
            for step in (*case.prefix, *case.steps):
                if step.channel != "control":
                    continue
                try:
                    sock.sendall(step.data.replace(SESSION, session))
                    answer = sock.recv(65536)
                except TimeoutError:
                    continue
                except OSError:
                    break
                if not answer:
                    break
                if session == b"none" and (found := _SESSION.search(answer)):
                    session = found.group(1)
    return time.perf_counter() - start


def timed(made: RctpCases) -> tuple[str, ...]:
    """The states the bench times: all but `stop unanswered` (see the docstring)."""
    return tuple(state for state in made.states if state != STOP_UNANSWERED)


def runner(target: RctpTarget, cases: list[TestCase]) -> float:
    start = time.perf_counter()
    for case in cases:
        target.judge(target.run(case))
    return time.perf_counter() - start


def campaign(target: RctpTarget, made: RctpCases, count: int, out: Path) -> float:
    budget = Budget(seconds=None, cases=count, max_rate=None, max_memory=512)
    whole = Campaign(target, made, out, 1, budget, {}, only=timed(made))
    start = time.perf_counter()
    whole.run()
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cases", type=int, default=400)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    robot = load_robot(REFERENCE_RCML)
    made = RctpCases(robot_paths(robot), control_seeds())
    rng = random.Random(7)
    cases = []
    for _ in range(args.cases):
        state = rng.choice(timed(made))
        kind = rng.choice([k for k in made.kinds(state) if not k.startswith("data-")])
        cases.append(made.make(state, kind, rng, rng.choice((1, 1, 2, 3))))
    address = ("127.0.0.1", free_port())
    times: dict[str, list[float]] = {"floor": [], "runner": [], "campaign": []}
    with (
        started(embedded_command(address[1], ()), address, 10.0),
        tempfile.TemporaryDirectory() as out,
    ):
        target = RctpTarget(address, robot, robot.site.path or "/", 5.0)
        for _ in range(args.rounds):
            times["floor"].append(bare_loop(address, cases))
            times["runner"].append(runner(target, cases))
            times["campaign"].append(campaign(target, made, args.cases, Path(out)))
        target.close()
    rates = {name: args.cases / statistics.median(spent) for name, spent in times.items()}
    result = {
        "cases": args.cases,
        "rounds": args.rounds,
        "cases_per_second": {name: round(rate, 1) for name, rate in rates.items()},
        "runner_vs_floor": round(rates["runner"] / rates["floor"], 3),
        "campaign_vs_floor": round(rates["campaign"] / rates["floor"], 3),
        "goal_runner_vs_floor": 0.30,
    }
    if args.json:
        print(json.dumps(result, indent=1))
        return
    for name, rate in rates.items():
        print(f"{name:9} {rate:8.1f} cases/s (median of {args.rounds})")
    print(
        f"runner/floor {result['runner_vs_floor']:.2f} (goal >= 0.30),"
        f" campaign/floor {result['campaign_vs_floor']:.2f}"
    )


if __name__ == "__main__":
    main()
