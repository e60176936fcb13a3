"""The experiments' figures, drawn with matplotlib on the Agg backend (no display needed).

matplotlib is imported here only, and only when a figure is drawn: the experiments run without
it (`pip install rcmlconf[plot]` brings it).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

from rcmlconf.experiments.packet_size import (
    MUSIC,
    PAPER_MOTION_SIZE,
    PAPER_MUSIC_SIZE,
    PacketSizeRun,
)
from rcmlconf.experiments.path_following import PathExperiment
from rcmlconf.experiments.path_reference import ReferencePath
from rcmlconf.experiments.path_run import Setting

if TYPE_CHECKING:
    from matplotlib.figure import Figure

#: Colours and labels of the transports (colour-blind-safe: Okabe and Ito's palette).
STYLES: dict[str, tuple[str, str]] = {
    "rsp": ("#0072B2", "RSP over UDP, motion filter"),
    "tcp": ("#D55E00", "fixed-size over TCP (timeout only)"),
    "tcp-linux": ("#E69F00", "fixed-size over TCP (SACK/RACK, CUBIC β)"),
    "tcp-small": ("#009E73", "RSP-sized over TCP (SACK/RACK, CUBIC β)"),
}


def _figure(width: float, height: float, columns: int = 1) -> tuple[Figure, Any]:
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    figure = Figure(figsize=(width, height), layout="constrained")
    axes = figure.subplots(1, columns) if columns > 1 else figure.subplots()
    return figure, axes


def packet_size_figure(runs: list[PacketSizeRun], out: Path) -> Path:
    """Fig. 10 again: every DOWNLINK's size over time, and the bytes against fixed sizes."""
    figure, (sizes, totals) = _figure(11, 4.2, 2)
    plain = runs[0]
    for section in plain.sections:
        if section.kind == MUSIC:
            for axes in (sizes, totals):
                axes.axvspan(section.start, section.end, color="0.92", lw=0)
        sizes.text(
            (section.start + section.end) / 2,
            1040,
            section.kind,
            ha="center",
            va="center",
            fontsize=12,
            color="0.35",
        )
    styles = ("-", "--", ":")
    for run, style in zip(runs, styles, strict=False):
        sizes.plot(
            run.times,
            run.sizes,
            style,
            lw=1.0,
            drawstyle="steps-post",
            label=f"RSP DOWNLINK, {_encryption(run)}",
        )
    for size, label in ((PAPER_MOTION_SIZE, "paper: 34 B"), (PAPER_MUSIC_SIZE, "paper: 1,992 B")):
        sizes.axhline(size, color="k", lw=0.6, ls=":")
        sizes.text(plain.duration, size, f" {label}", va="center", fontsize=8)
    first = plain.sections[0]
    motion = " / ".join(f"{min(r.sizes_in('A'))} B" for r in runs)
    sizes.annotate(
        f"A: {motion}",
        ((first.start + first.end) / 2, min(plain.sizes_in("A"))),
        ((first.start + first.end) / 2, 400),
        ha="left",
        arrowprops={"arrowstyle": "->", "lw": 0.7},
        fontsize=9,
    )
    sizes.set_xlim(0, plain.duration)
    sizes.set_ylim(0, 2200)
    sizes.set_xlabel("time (s)")
    sizes.set_ylabel("packet size (bytes, UDP payload)")
    sizes.set_title("Variable packet size (cf. paper Fig. 10)")
    sizes.legend(loc="upper left", fontsize=8)

    cumulative = _cumulative(plain.sizes)
    count = len(plain.sizes)
    times = plain.times
    totals.plot(times, [b / 1e6 for b in cumulative], label="RSP, no encryption", color="#0072B2")
    for fixed, label, colour in (
        (plain.largest, f"fixed {plain.largest:,} B (largest sent)", "#D55E00"),
        (plain.model_largest, f"fixed {plain.model_largest:,} B (model's largest)", "#E69F00"),
    ):
        totals.plot(
            times,
            [fixed * (i + 1) / 1e6 for i in range(count)],
            label=f"{label}: saving {plain.saving(fixed) * 100:.2f} %",
            color=colour,
        )
    totals.set_xlim(0, plain.duration)
    totals.set_xlabel("time (s)")
    totals.set_ylabel("DOWNLINK bytes sent (MB)")
    totals.set_title("Bytes sent against fixed-size packets")
    totals.legend(loc="upper left", fontsize=8)
    out.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(out, dpi=120)
    return out


def _encryption(run: PacketSizeRun) -> str:
    name = run.encryption.name
    return "no encryption" if name == "NONE" else name.replace("_", "-")


def _cumulative(values: list[int]) -> list[int]:
    total = 0
    out = []
    for value in values:
        total += value
        out.append(total)
    return out


def path_figure(
    experiment: PathExperiment,
    settings: list[Setting],
    out: Path,
    path: ReferencePath | None = None,
) -> Path:
    """Fig. 11 again: the robot's true paths over the reference path, one panel a setting; a
    dot marks where each robot was at the end (a robot that never left the start is a dot)."""
    path = path or ReferencePath()
    figure, panels = _figure(6.2 * len(settings), 5.6, len(settings))
    if len(settings) == 1:
        panels = [panels]
    xs = [p.x for p in path.points] + [path.points[0].x]
    ys = [p.y for p in path.points] + [path.points[0].y]
    for axes, where in zip(panels, settings, strict=True):
        axes.plot(xs, ys, "k--", lw=1.2, label="reference path")
        start = path.start
        axes.plot([start.x], [start.y], "k>", ms=8)
        for run in experiment.runs:
            if run.setting != where:
                continue
            colour, label = STYLES.get(run.transport, ("0.5", run.transport))
            label = f"{label}: {run.mean_error * 100:.1f} cm, lap {run.completion * 100:.0f} %"
            if run.completion == 0 and run.max_error < 0.01:
                label += " (never left the start)"
            axes.plot(run.xs, run.ys, color=colour, lw=1.3, label=label)
            axes.plot(run.xs[-1:], run.ys[-1:], "o", color=colour, ms=5)
        axes.set_aspect("equal", adjustable="datalim")
        axes.set_xlabel("x (m)")
        axes.set_ylabel("y (m)")
        axes.set_title(f"{where.label}")
        axes.legend(loc="upper center", bbox_to_anchor=(0.5, -0.12), fontsize=8)
    figure.suptitle("Path following at T = 20 ms (cf. paper Fig. 11): mean path error, lap done")
    out.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(out, dpi=120)
    return out
