"""How many faults of the reference does `rcmlconf run` kill? (issue 16, item 5)

The goal: at least 90 % of the non-equivalent mutants of a seeded sample of 300 or more killed,
every survivor triaged in bench/mutation_survivors.md.

Mutation testing of the reference's protocol logic, killed by the conformance suite, not by the
unit tests. Cosmic Ray's operators (comparison, binary and unary operators, and/or, True/False,
numbers, break/continue, `not`, exceptions, decorators, empty loops: every operator that takes no
arguments) list every mutant of the modules below, less those in annotations (never evaluated
here: `from __future__ import annotations`); a seeded sample of `--sample` of them is drawn
across all the modules; each mutant is written into a copy of the package (one copy per worker,
in a temporary directory: the working tree is never touched) and `python -m rcmlconf run` is run
from that copy with only the cases of the role the mutated module serves:

    server  rcmlconf/reference/server/{adapter,files,privileges,robot,session}.py
            --only 'rctp/*' --skip 'rctp/client/*'
    robot   rcmlconf/reference/rsp/robot.py, rcmlconf/rsp/session/robot.py
            --only 'rsp/*' --skip 'rsp/local/*'
    client  rcmlconf/reference/client/{adapter,files,session}.py      --only 'rctp/client/*'
    local   rcmlconf/reference/rsp/simulacrum.py, rcmlconf/rsp/session/local.py
            --only 'rsp/local/*'
    rsp     rcmlconf/rsp/session/{devices,events,timing,wire}.py (both sides use them)
            --only 'rsp/*'

Left out, as not protocol logic or not on the suite's path: reference/server/faulty_*.py
(the --fault machinery: its code runs only when a fault is asked for), reference/rsp/batch.py
(many endpoints on one loop, for the scale benches: the suite's reference does not use it),
reference/rsp/{bodies,cubo}.py (the simulated bodies' physics), reference/rsp/log_text.py (the
robot's log), the __init__ modules, and reference/drivers/ (the RCTP robots' simulated values).

Exit status 0 of the run, every case pass or not applicable: the mutant survived. Otherwise
killed, shown by how: `failed` (1: a case failed), `error` (2 or another status: the harness,
the reference or the import broke), `timeout` (the run outlived --timeout and was killed with its
process group) or `inconclusive` (exit 0, but a case could not tell, in two runs: a timing
excused once on a loaded machine is not a kill). An inconclusive run is what `rcmlconf run
--strict` fails, as a CI gate that wants every case decided runs it: the reference's client and
local system follow written scenarios (D-RCTP-31, D-RSP-24) that bind no requirement of their
own, so a mutant that leaves a step out shows as the steps' cases unable to tell. The report
gives both rates: `strict` counts those kills, `default` does not. Before the mutants, each
role's cases run on the unmutated copy: they must pass with none inconclusive (up to three
tries), or nothing is measured.

Kill rate = killed / (mutants - equivalent known), in each of the two ways. An equivalent is a
survivor that bench/mutation_survivors.md (or --triage) marks `equivalent`, matched by module,
operator, occurrence and mutated line (an edit of the module unmatches it: it is triaged anew).
Survivors go to --survivors as JSON: module, line, operator, occurrence, the line before and
after, and the triage file's verdict if it has one.

The harness's own RSP probes use rcmlconf/rsp/session/ too (LocalEndpoint and SessionWire play
the local system to the robot under test; the cases read its HELLO and keepalive constants): a
mutant there changes both ends of the test, and its kill may be the harness breaking (`error`).

A mutant costs one run of its role's cases: on the development machine, about 1 s (client), 8 s
(server), 10 s (robot, local, rsp), longer when the mutant slows the run down, 60 s when it hangs
it. Two samples of 20 on 2 workers took 125 s and 152 s of wall time (8 s and 10 s a mutant on
average, about 30 s of it the unmutated runs): 300 mutants take about half an hour on 2 cores.

Needs Cosmic Ray: `pip install -e '.[bench]'`.

    python bench/suite_mutation_score.py --sample 20 --survivors /tmp/survivors.json
    python bench/suite_mutation_score.py            # 300 mutants, seed 0, 2 workers
"""

from __future__ import annotations

import argparse
import ast
import contextlib
import json
import os
import random
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections import Counter
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
TRIAGE = ROOT / "bench" / "mutation_survivors.md"

#: The runs under way: they have sessions of their own (a timeout kills a run's whole group), so
#: an interrupt does not reach them, and the script ends them itself.
RUNS: set[subprocess.Popen[bytes]] = set()

#: The cases of each role: (--only globs, --skip globs).
ROLES: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    "server": (("rctp/*",), ("rctp/client/*",)),
    "robot": (("rsp/*",), ("rsp/local/*",)),
    "client": (("rctp/client/*",), ()),
    "local": (("rsp/local/*",), ()),
    "rsp": (("rsp/*",), ()),
}

#: The mutated modules and the role each serves (see the docstring for those left out).
MODULES: dict[str, str] = {
    **{f"rcmlconf/reference/server/{m}.py": "server" for m in ("adapter", "files", "privileges")},
    **{f"rcmlconf/reference/server/{m}.py": "server" for m in ("robot", "session")},
    "rcmlconf/reference/rsp/robot.py": "robot",
    "rcmlconf/rsp/session/robot.py": "robot",
    **{f"rcmlconf/reference/client/{m}.py": "client" for m in ("adapter", "files", "session")},
    "rcmlconf/reference/rsp/simulacrum.py": "local",
    "rcmlconf/rsp/session/local.py": "local",
    **{f"rcmlconf/rsp/session/{m}.py": "rsp" for m in ("devices", "events", "timing", "wire")},
}


@dataclass(frozen=True)
class Mutant:
    module: str
    operator: str
    occurrence: int
    line: int

    @property
    def role(self) -> str:
        return MODULES[self.module]


@dataclass
class Outcome:
    mutant: Mutant
    how: str  # survived, failed, error, timeout, inconclusive, no mutation
    seconds: float
    original: str = ""
    mutated: str = ""
    unsure: tuple[str, ...] = ()  # the cases that came out inconclusive


def all_mutants() -> list[Mutant]:
    """Every mutant of every module, in a stable order (so that a seed draws the same sample),
    less those in annotations."""
    from cosmic_ray.ast import ast_nodes, get_ast_from_path
    from cosmic_ray.plugins import get_operator, operator_names

    operators = [(n, get_operator(n)) for n in sorted(operator_names())]
    found = []
    for module in MODULES:
        tree = get_ast_from_path(ROOT / module)
        unread = annotations((ROOT / module).read_text(encoding="utf-8"))
        for name, operator_class in operators:
            if operator_class.arguments():
                continue  # VariableReplacer/Inserter: they need arguments to mean anything
            operator = operator_class()
            positions = (p for node in ast_nodes(tree) for p in operator.mutation_positions(node))
            # The occurrence counts every position: it is what Cosmic Ray's mutator takes.
            for occurrence, (start, _end) in enumerate(positions):
                if not any(first <= start <= last for first, last in unread):
                    found.append(Mutant(module, name, occurrence, start[0]))
    return found


Span = tuple[tuple[int, int], tuple[int, int]]


def annotations(source: str) -> list[Span]:
    """Where the annotations of a module are, if it never evaluates them (`from __future__ import
    annotations`, PEP 563): a mutant there (`bytes | None` to `bytes >> None`) is equivalent by
    construction, and would only pad the sample."""
    tree = ast.parse(source)
    lazy = any(
        isinstance(n, ast.ImportFrom)
        and n.module == "__future__"
        and any(a.name == "annotations" for a in n.names)
        for n in tree.body
    )
    if not lazy:
        return []
    found: list[ast.expr] = []
    for node in ast.walk(tree):
        annotation: ast.expr | None = None
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            annotation = node.returns
        elif isinstance(node, ast.arg | ast.AnnAssign):
            annotation = node.annotation
        if annotation is not None:
            found.append(annotation)
    return [
        ((a.lineno, a.col_offset), (a.end_lineno or a.lineno, a.end_col_offset or 0)) for a in found
    ]


def mutate(source: str, mutant: Mutant) -> str | None:
    """The module's source with the mutant in, or None if Cosmic Ray finds nothing to mutate."""
    from cosmic_ray.mutating import mutate_code
    from cosmic_ray.plugins import get_operator

    mutated: str | None = mutate_code(source, get_operator(mutant.operator)(), mutant.occurrence)
    return mutated


def copy_package(into: Path) -> Path:
    """A copy of the package (and the specs it reads at run time) that runs can mutate."""
    ignore = shutil.ignore_patterns("__pycache__")
    shutil.copytree(ROOT / "rcmlconf", into / "rcmlconf", ignore=ignore)
    shutil.copytree(ROOT / "specs", into / "specs", ignore=ignore)
    return into


def forget_bytecode(path: Path) -> None:
    # A mutant often keeps the file's size, and a .pyc is checked by size and mtime in whole
    # seconds: a stale one would run the previous mutant (or the original) instead.
    for pyc in (path.parent / "__pycache__").glob(f"{path.stem}.*.pyc"):
        pyc.unlink(missing_ok=True)


def run_suite(copy: Path, role: str, timeout: float) -> tuple[str, float, list[str]]:
    """Run the role's cases from `copy`: (how, seconds, the cases that came out inconclusive)."""
    only, skip = ROLES[role]
    report = copy / f"run-{threading.get_ident()}.json"
    report.unlink(missing_ok=True)
    command = [sys.executable, "-m", "rcmlconf", "run", "--json", str(report)]
    command += [a for glob in only for a in ("--only", glob)]
    command += [a for glob in skip for a in ("--skip", glob)]
    env = {**os.environ, "PYTHONPATH": str(copy)}
    started = time.perf_counter()
    process = subprocess.Popen(
        command,
        cwd=copy,
        env=env,
        stdin=subprocess.DEVNULL,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,  # so that a timeout kills the run and whatever it started
    )
    RUNS.add(process)
    try:
        status = process.wait(timeout)
    except subprocess.TimeoutExpired:
        end(process)
        process.wait()
        return "timeout", time.perf_counter() - started, []
    finally:
        RUNS.discard(process)
    seconds = time.perf_counter() - started
    unsure = inconclusive(report)
    if status == 0 and unsure:
        return "inconclusive", seconds, unsure
    return {0: "survived", 1: "failed"}.get(status, "error"), seconds, unsure


def inconclusive(report: Path) -> list[str]:
    """The cases a run's --json report calls inconclusive (none when it wrote no report)."""
    try:
        results = json.loads(report.read_text(encoding="utf-8"))["results"]
    except (OSError, ValueError, KeyError):
        return []
    return sorted({r["case"] for r in results if r.get("verdict") == "inconclusive"})


def end(process: subprocess.Popen[bytes]) -> None:
    with contextlib.suppress(ProcessLookupError):
        os.killpg(process.pid, signal.SIGKILL)


def try_mutant(copy: Path, mutant: Mutant, timeout: float) -> Outcome:
    path = copy / mutant.module
    source = path.read_text(encoding="utf-8")
    mutated = mutate(source, mutant)
    if mutated is None:
        return Outcome(mutant, "no mutation", 0.0)
    before = source.splitlines()[mutant.line - 1].strip()
    after_lines = mutated.splitlines()
    after = after_lines[mutant.line - 1].strip() if mutant.line <= len(after_lines) else ""
    try:
        path.write_text(mutated, encoding="utf-8")
        forget_bytecode(path)
        how, seconds, unsure = run_suite(copy, mutant.role, timeout)
        if how == "inconclusive":  # a timing excused on a loaded machine is not a kill: again
            how, again, unsure = run_suite(copy, mutant.role, timeout)
            seconds += again
    finally:
        path.write_text(source, encoding="utf-8")
        forget_bytecode(path)
    return Outcome(mutant, how, seconds, before, after, tuple(unsure))


Key = tuple[str, str, int, str]


def key(outcome: Outcome) -> Key:
    """What a triage row is matched by: module, operator, occurrence and mutated line."""
    m = outcome.mutant
    return m.module, m.operator, m.occurrence, outcome.mutated


def verdicts(triage: Path) -> dict[Key, str]:
    """The verdict of each row of the triage file, by what it is matched by."""
    if not triage.exists():
        return {}
    found = {}
    for row in triage.read_text(encoding="utf-8").splitlines():
        cells = [c.strip().replace("\\|", "|") for c in re.split(r"(?<!\\)\|", row)[1:-1]]
        if len(cells) < 6 or not cells[0].startswith("rcmlconf/") or not cells[3].isdigit():
            continue
        module, _line, operator, occurrence, mutated, verdict = cells[:6]
        found[module, operator, int(occurrence), mutated.strip("`")] = verdict
    return found


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n", 1)[0],
        epilog=__doc__.split("\n", 1)[1],
        formatter_class=_Raw,
    )
    parser.add_argument("--sample", type=int, default=300, help="mutants drawn (default 300)")
    parser.add_argument("--seed", type=int, default=0, help="seeds the draw (default 0)")
    parser.add_argument("--workers", type=int, default=2, help="runs at once (default 2)")
    parser.add_argument(
        "--timeout", type=float, default=60.0, help="seconds a mutant's run may take (60)"
    )
    parser.add_argument("--survivors", type=Path, help="write the survivors here (JSON)")
    parser.add_argument(
        "--triage",
        type=Path,
        default=TRIAGE,
        help="the triage file (default bench/mutation_survivors.md)",
    )
    args = parser.parse_args()
    if args.sample < 1 or args.workers < 1 or not 0 < args.timeout <= 86400:
        parser.error("--sample and --workers must be at least 1, --timeout in (0, 86400]")

    started = time.perf_counter()
    everything = all_mutants()
    sample = random.Random(args.seed).sample(everything, min(args.sample, len(everything)))
    roles = sorted({m.role for m in sample})
    print(
        f"{len(everything)} mutants in {len(MODULES)} modules; drew {len(sample)} (seed "
        f"{args.seed}); roles {', '.join(roles)}",
        flush=True,
    )

    outcomes: list[Outcome] = []
    with tempfile.TemporaryDirectory(prefix="mutation-") as top:
        copies = [copy_package(Path(top) / f"w{n}") for n in range(args.workers)]
        # The unmutated cases must pass, none inconclusive, or a kill means nothing.
        for role in roles:
            for _ in range(3):  # a timing excused once on a loaded machine: again
                how, seconds, unsure = run_suite(copies[0], role, args.timeout)
                print(
                    f"unmutated {role:7} {how:12} {seconds:6.1f} s {' '.join(unsure)}", flush=True
                )
                if how != "inconclusive":
                    break
            if how != "survived":
                sys.exit(f"the unmutated {role} cases did not pass ({how}): nothing measured")
        free = list(copies)
        lock = threading.Lock()

        def one(mutant: Mutant) -> Outcome:
            with lock:
                copy = free.pop()
            try:
                outcome = try_mutant(copy, mutant, args.timeout)
            finally:
                with lock:
                    free.append(copy)
            where = f"{mutant.module}:{mutant.line}"
            unsure = f"  ({', '.join(outcome.unsure[:3])})" if outcome.how == "inconclusive" else ""
            print(
                f"{outcome.how:12} {outcome.seconds:6.1f} s  {where}  {mutant.operator}{unsure}",
                flush=True,
            )
            return outcome

        pool = ThreadPoolExecutor(args.workers)
        try:
            outcomes = list(pool.map(one, sample))
        except KeyboardInterrupt:
            pool.shutdown(wait=False, cancel_futures=True)
            for process in list(RUNS):
                end(process)
            pool.shutdown()
            sys.exit("interrupted: nothing measured")
        pool.shutdown()
    report(outcomes, verdicts(args.triage), time.perf_counter() - started, args)


def report(
    outcomes: list[Outcome],
    triaged: dict[Key, str],
    wall: float,
    args: argparse.Namespace,
) -> None:
    tried = [o for o in outcomes if o.how != "no mutation"]
    survivors = [o for o in tried if o.how == "survived"]
    equivalent = [o for o in survivors if triaged.get(key(o), "").startswith("equivalent")]
    print()
    print(
        f"{'module':42} {'role':7} {'mutants':>7} {'killed':>6} {'timeout':>7} "
        f"{'unsure':>6} {'equiv':>5} {'survived':>8} {'strict':>6} {'default':>7}"
    )
    for module, role in MODULES.items():
        mine = [o for o in tried if o.mutant.module == module]
        if mine:
            print(row(module, role, mine, equivalent))
    print(row("all", "", tried, equivalent))
    hows = Counter(o.how for o in tried)
    print(
        f"killed by how: failed {hows['failed']}, error {hows['error']}, "
        f"timeout {hows['timeout']} (--timeout {args.timeout:g} s), inconclusive "
        f"{hows['inconclusive']} (twice: killed under --strict only)"
    )
    if tried:
        mean = sum(o.seconds for o in tried) / len(tried)
        print(f"seconds a mutant: mean {mean:.1f}, longest {max(o.seconds for o in tried):.1f}")
    print(f"wall: {wall:.0f} s on {args.workers} workers")
    needed = [o for o in survivors if key(o) in triaged and o not in equivalent]
    new = [o for o in survivors if key(o) not in triaged]
    print(
        f"survivors: {len(equivalent)} equivalent, {len(needed)} triaged as not equivalent, "
        f"{len(new)} not triaged yet (in {args.triage.name})"
    )
    if args.survivors is not None:
        rows = [
            {
                **asdict(o.mutant),
                "role": o.mutant.role,
                "original": o.original,
                "mutated": o.mutated,
                "verdict": triaged.get(key(o)),
            }
            for o in survivors
        ]
        args.survivors.write_text(json.dumps(rows, indent=2) + "\n", encoding="utf-8")
        print(f"survivors written to {args.survivors}")


def row(name: str, role: str, mine: list[Outcome], equivalent: list[Outcome]) -> str:
    """The module's figures: `strict` counts a mutant whose run had a case inconclusive (twice)
    as killed, as `rcmlconf run --strict` fails it; `default` counts only fail, error, timeout."""
    killed = sum(o.how != "survived" for o in mine)
    timeouts = sum(o.how == "timeout" for o in mine)
    unsure = sum(o.how == "inconclusive" for o in mine)
    equiv = sum(o in equivalent for o in mine)
    counted = len(mine) - equiv
    strict = f"{killed / counted:6.1%}" if counted else "     -"
    default = f"{(killed - unsure) / counted:7.1%}" if counted else "      -"
    return (
        f"{name:42} {role:7} {len(mine):7} {killed:6} {timeouts:7} {unsure:6} {equiv:5} "
        f"{len(mine) - killed:8} {strict} {default}"
    )


class _Raw(argparse.RawDescriptionHelpFormatter):
    pass


if __name__ == "__main__":
    main()
