"""The reference path of experiment 2: its length, and its distance field exact on and off it."""

from __future__ import annotations

import math

import pytest

from rcmlconf.experiments.path_reference import ReferencePath


def test_the_reference_path() -> None:
    path = ReferencePath()
    assert path.length == pytest.approx(2 * 1.4 + 2 * 0.4 + 2 * math.pi * 0.3, abs=1e-3)
    assert max(path.distance(p.x, p.y) for p in path.points) < 1e-9
    assert path.distance(0.0, 0.0) == pytest.approx(0.5)
    assert path.distance(1.2, 0.0) == pytest.approx(0.2)
    corner = 0.7 + 0.3 / math.sqrt(2), 0.2 + 0.3 / math.sqrt(2)
    assert path.distance(corner[0] + 0.1, corner[1] + 0.1) == pytest.approx(0.1 * math.sqrt(2))
