"""The report's timeline (states over time) stays bounded however long a campaign runs, and
keeps its first and newest points in order."""

from __future__ import annotations

from rcmlconf.fuzz.campaign import TIMELINE, Stats


def test_a_week_of_ticks_keeps_at_most_the_bound_in_order() -> None:
    stats = Stats()
    for second in range(7 * 86400 // 60):  # a tick a minute for a week: 10,080
        stats.elapsed, stats.cases, stats.states = float(second), second * 100, min(second, 7)
        stats.mark()
    points = stats.timeline
    assert len(points) <= TIMELINE
    assert points[0] == (0.0, 0, 0, 0)
    assert points[-1][0] == 7 * 86400 // 60 - 1
    assert [p[0] for p in points] == sorted(p[0] for p in points)
