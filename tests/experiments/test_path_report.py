"""Experiment 2's report and figure, from two short runs."""

from __future__ import annotations

from pathlib import Path

from support.rsp_models import robot_model

from rcmlconf.experiments.path_following import DEFAULT_BANDWIDTH, PathExperiment, run_path
from rcmlconf.experiments.path_report import report
from rcmlconf.experiments.path_run import setting
from rcmlconf.experiments.plots import path_figure

PNG = b"\x89PNG\r\n\x1a\n"
#: Seconds of lap after the warm-up: about a third of it.
DURATION = 8.0


def test_the_figure(tmp_path: Path) -> None:
    where = setting(0.1, 0.01)
    runs = [run_path(robot_model(), t, where, duration=DURATION) for t in ("rsp", "tcp")]
    experiment = PathExperiment(runs, DURATION, DEFAULT_BANDWIDTH, 0)
    out = path_figure(experiment, [where], tmp_path / "fig11.png")
    assert out.read_bytes().startswith(PNG)
    text = report(experiment, robot_model(), "fig11.png")
    assert "| 100 ± 20 ms | 1 % |" in text
