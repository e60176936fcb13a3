"""Experiment 2 of the RSP paper (§IV.B, Fig. 11): path following under delay and loss.

A simulated local system drives a simulated CUBO round a rounded rectangle with pure pursuit,
from the positions it receives every T = 20 ms, over RSP and over fixed-size packets on TCP,
through a sweep of delays and losses (rcmlconf.experiments.path_following says what each
transport is). Writes a figure like Fig. 11, the figures as JSON and a Markdown report beside
the paper's.

    python bench/rsp_path_following.py [--out-dir bench/out] [--seed 0] [--duration 25] [--quick]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from rcmlconf.experiments import path_following as pf
from rcmlconf.experiments import plots
from rcmlconf.experiments.path_report import report
from rcmlconf.experiments.path_run import setting
from rcmlconf.experiments.simulation import cubo_model

ROOT = Path(__file__).resolve().parent.parent


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out-dir", type=Path, default=ROOT / "bench" / "out")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--duration", type=float, default=pf.DEFAULT_DURATION)
    parser.add_argument(
        "--bandwidth", type=float, default=pf.DEFAULT_BANDWIDTH, help="bits/s each way"
    )
    parser.add_argument(
        "--quick", action="store_true", help="two settings, 5 s runs, no extra bandwidths"
    )
    parser.add_argument("--report", type=Path, help="the Markdown report (default: in --out-dir)")
    args = parser.parse_args()
    model = cubo_model()
    began = time.perf_counter()
    if args.quick:
        figure_settings = [setting(0.1, 0.01), setting(0.1, 0.1)]
        experiment = pf.run_sweep(
            model, delays=(0.1,), losses=(0.01, 0.1), duration=5.0, seed=args.seed,
            bandwidth=args.bandwidth,
        )  # fmt: skip
    else:
        figure_settings = [setting(*s) for s in pf.FIGURE_SETTINGS]
        experiment = pf.run_sweep(
            model, duration=args.duration, seed=args.seed, bandwidth=args.bandwidth
        )
        experiment.extra = pf.run_extra(model, duration=args.duration, seed=args.seed)
    out: Path = args.out_dir
    out.mkdir(parents=True, exist_ok=True)
    figure = plots.path_figure(experiment, figure_settings, out / "rsp_path_following.png")
    report_path: Path = args.report or out / "rsp_path_following.md"
    report_path.parent.mkdir(parents=True, exist_ok=True)
    link = _relative(figure, report_path.parent)
    report_path.write_text(report(experiment, model, link), encoding="utf-8")
    data = {"experiment": "path following (paper Fig. 11)", **experiment.summary()}
    (out / "rsp_path_following.json").write_text(json.dumps(data, indent=1), encoding="utf-8")
    print(f"{'delay':>6} {'loss':>5}  " + "  ".join(f"{t:>16}" for t in pf.TRANSPORTS))
    for where in dict.fromkeys(r.setting for r in experiment.runs):
        cells = []
        for transport in pf.TRANSPORTS:
            run = experiment.find(transport, where.delay, where.loss)
            cells.append(
                f"{run.mean_error * 100:7.2f} cm {run.completion * 100:4.0f} %" if run else "-"
            )
        print(f"{where.delay * 1000:4g}ms {where.loss * 100:4g}%  " + "  ".join(cells))
    print("(mean path error, share of the lap done)")
    print(f"{len(experiment.runs) + len(experiment.extra)} runs in "
          f"{time.perf_counter() - began:.1f} s; wrote {figure}, "
          f"{out / 'rsp_path_following.json'}, {report_path}")  # fmt: skip


def _relative(target: Path, base: Path) -> str:
    try:
        return str(target.resolve().relative_to(base.resolve()))
    except ValueError:
        return str(target.resolve())


if __name__ == "__main__":
    main()
