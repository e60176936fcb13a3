"""States reached over time by `rcmlconf fuzz`, one campaign a role, against the embedded
references (issue 29): the server, the robot (CUBO), the client and the local system (CUBO).

Each campaign runs as a user runs it (`rcmlconf fuzz ... --seconds S`), one after another, and
its report's `timeline` ([seconds, cases, states, findings] about once a second) is drawn: the
states reached, and the cases run, over the campaign's time. Prints, for each role, when the
campaign had reached all its states and the cases a second. Writes bench/out/fuzz_states.png
(matplotlib, the `plot` extra) and the timelines as JSON beside it.

    python bench/fuzz_states.py [--seconds 30] [--out-dir bench/out]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

from rcmlconf.conformance.targets import REFERENCE_RMODEL

ROOT = Path(__file__).resolve().parent.parent
ROLES: dict[str, list[str]] = {
    "server": [],
    "robot": ["--model", str(REFERENCE_RMODEL)],
    "client": ["--role", "client"],
    "local": ["--role", "local", "--model", str(REFERENCE_RMODEL)],
}


def campaign(role: str, seconds: float, folder: Path) -> dict[str, Any]:
    out = folder / role
    command = [sys.executable, "-m", "rcmlconf", "fuzz", *ROLES[role], "--seconds", str(seconds)]
    done = subprocess.run(
        [*command, "--seed", "1", "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=seconds * 3 + 60,
        check=False,
    )
    if done.returncode not in (0, 1):
        raise SystemExit(f"{role}: {done.stderr.strip()}")
    report: dict[str, Any] = json.loads((out / "report.json").read_text())
    return report


def all_states_at(report: dict[str, Any]) -> float | None:
    """When the campaign first had every state it reached in the end."""
    final = report["states_reached"]
    return next((point[0] for point in report["timeline"] if point[2] >= final), None)


def figure(reports: dict[str, dict[str, Any]], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (states, cases) = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    for role, report in reports.items():
        times = [point[0] for point in report["timeline"]]
        states.step(times, [point[2] for point in report["timeline"]], where="post", label=role)
        cases.plot(times, [point[1] for point in report["timeline"]], label=role)
    states.set_ylabel("states reached")
    cases.set_ylabel("cases run")
    cases.set_yscale("log")
    cases.set_xlabel("seconds")
    states.legend()
    states.set_title("rcmlconf fuzz against the embedded references")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=30.0)
    parser.add_argument("--out-dir", type=Path, default=ROOT / "bench" / "out")
    args = parser.parse_args()
    args.out_dir.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as folder:
        reports = {role: campaign(role, args.seconds, Path(folder)) for role in ROLES}
    print(f"{'role':<8} {'cases':>7} {'cases/s':>8} {'states':>7} {'all by':>8} {'findings':>9}")
    for role, report in reports.items():
        at = all_states_at(report)
        shown = f"{at:.1f} s" if at is not None else "-"
        print(
            f"{role:<8} {report['cases']:>7} {report['cases_per_second']:>8.1f}"
            f" {report['states_reached']:>7} {shown:>8} {len(report['findings']):>9}"
        )
    timelines = {role: report["timeline"] for role, report in reports.items()}
    (args.out_dir / "fuzz_states.json").write_text(json.dumps(timelines) + "\n")
    figure(reports, args.out_dir / "fuzz_states.png")
    print(f"wrote {args.out_dir / 'fuzz_states.png'}")


if __name__ == "__main__":
    main()
