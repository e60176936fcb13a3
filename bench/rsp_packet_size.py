"""Experiment 1 of the RSP paper (§IV.B, Fig. 10): the variable packet size.

A simulated local system sends lip and arm motion to a simulated CUBO every T = 20 ms for two
minutes, with music in some sections (rcmlconf.experiments.packet_size says which and why), once
without encryption and once with AES-256-GCM, and measures every DOWNLINK. Writes a figure like
Fig. 10, the figures as JSON and a Markdown report beside the paper's.

    python bench/rsp_packet_size.py [--out-dir bench/out] [--seed 0] [--duration 120] [--quick]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from rcmlconf.experiments import packet_size, plots
from rcmlconf.experiments.simulation import cubo_model
from rcmlconf.rsp.codec import Encryption

ROOT = Path(__file__).resolve().parent.parent


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out-dir", type=Path, default=ROOT / "bench" / "out")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--duration", type=float, default=packet_size.PAPER_DURATION)
    parser.add_argument("--quick", action="store_true", help="12 s instead of two minutes")
    parser.add_argument("--report", type=Path, help="the Markdown report (default: in --out-dir)")
    args = parser.parse_args()
    duration = 12.0 if args.quick else args.duration
    model = cubo_model()
    runs = [
        packet_size.run_packet_size(model, duration=duration, seed=args.seed, encryption=e)
        for e in (Encryption.NONE, Encryption.AES_256_GCM)
    ]
    out: Path = args.out_dir
    out.mkdir(parents=True, exist_ok=True)
    figure = plots.packet_size_figure(runs, out / "rsp_packet_size.png")
    report_path: Path = args.report or out / "rsp_packet_size.md"
    report_path.parent.mkdir(parents=True, exist_ok=True)
    link = Path(_relative(figure, report_path.parent))
    report_path.write_text(packet_size.report(runs, str(link)), encoding="utf-8")
    data = {
        "experiment": "packet size (paper Fig. 10)",
        "duration": duration,
        "seed": args.seed,
        "schedule": [vars_of(s) for s in runs[0].sections],
        "runs": [run.summary() for run in runs],
    }
    (out / "rsp_packet_size.json").write_text(json.dumps(data, indent=1), encoding="utf-8")
    for run in runs:
        s = run.summary()
        print(
            f"{run.encryption.name:18} A {s['sizes_motion_only']}  B {s['sizes_with_music']}  "
            f"saving {s['saving_vs_largest_sent'] * 100:.2f} % (paper 38.65 %), "
            f"{s['saving_vs_model_largest'] * 100:.2f} % vs the model's largest"
        )
    print(f"wrote {figure}, {out / 'rsp_packet_size.json'}, {report_path}")


def vars_of(section: packet_size.Section) -> dict[str, object]:
    return {"kind": section.kind, "start": section.start, "end": section.end}


def _relative(target: Path, base: Path) -> str:
    try:
        return str(target.resolve().relative_to(base.resolve()))
    except ValueError:
        return str(target.resolve())


if __name__ == "__main__":
    main()
