"""Option types every command shares: numbers that are finite and inside a documented range.

click's FloatRange takes `nan`, `inf` and `1e309` (NaN compares false with every bound, and an
open upper end lets infinity in): `--hold nan` held forever and `--timeout-scale nan` failed cases
that never ran. Every float option of rcmlconf is a `Bounded`: a finite number, between two
bounds that `--help` prints.
"""

from __future__ import annotations

import math
from typing import Any

import click


class Bounded(click.FloatRange):
    """A finite float in [low, high] (either end open if asked); `--help` shows the range."""

    name = "number"

    def __init__(
        self, low: float, high: float, *, low_open: bool = False, high_open: bool = False
    ) -> None:
        super().__init__(low, high, min_open=low_open, max_open=high_open)

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        number = click.FLOAT.convert(value, param, ctx)
        if not math.isfinite(number):
            self.fail(f"{value!r} is not a finite number.", param, ctx)
        return super().convert(number, param, ctx)


def seconds(high: float, low: float = 0.0) -> Bounded:
    """A duration in seconds: more than `low` (0 by default), at most `high`."""
    return Bounded(low, high, low_open=True)


#: A day: the longest any command waits, holds or runs when told a time (a longer run is
#: open-ended: leave the option out and stop it with Ctrl-C).
DAY = 86_400.0
