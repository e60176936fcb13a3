"""The HTML report's plot of a case's datagrams, as inline SVG: the interval before each UDP
datagram the harness received (a stream's or an RSP session's pace, its jitter) over the case's
time, and a red tick for each one lost or withheld: by the impairment, not sent, or missing
from a data stream's numbering (R-RCTP-41: one more each, modulo 65,536). Where the transcript
left datagrams out (a note with a transport), no interval and no numbering spans the gap."""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from itertools import pairwise
from typing import Any

from rcmlconf.conformance.transcript import LEFT_OUT

WIDTH, HEIGHT = 360, 90
#: Room for the axis' labels.
_LEFT, _BOTTOM = 44, 14
#: A plot needs this many intervals to show a pace.
_FEWEST = 2
#: A data stream packet's number as the transcript shows it (`udp HOST:PORT seq N tag ...`).
_SEQUENCE = re.compile(r"\budp \S+ seq (\d+)\b")
_NUMBERS = 1 << 16


def interval_plot(entries: Sequence[Mapping[str, Any]]) -> str:
    """The SVG, or "" for an exchange with too few datagrams received and none lost."""
    arrivals = [float(e["time"]) for e in entries if _arrival(e)]
    lost = [float(e["time"]) for e in entries if _lost(e)] + _skipped(entries)
    times = [float(e["time"]) if _arrival(e) else None for e in entries if _arrival(e) or _gap(e)]
    intervals = [
        (later, later - earlier)
        for earlier, later in pairwise(times)
        if earlier is not None and later is not None
    ]
    if len(intervals) < _FEWEST and not lost:
        return ""
    end = max([*arrivals, *lost, 1e-3])
    top = max([gap for _, gap in intervals] + [1e-3])

    def x(at: float) -> float:
        return _LEFT + (WIDTH - _LEFT - 4) * at / end

    def y(gap: float) -> float:
        return 4 + (HEIGHT - _BOTTOM - 8) * (1 - gap / top)

    points = " ".join(f"{x(at):.1f},{y(gap):.1f}" for at, gap in intervals)
    ticks = "".join(
        f'<line class="lost" x1="{x(at):.1f}" x2="{x(at):.1f}" y1="{HEIGHT - _BOTTOM}"'
        f' y2="{HEIGHT - _BOTTOM - 10}" stroke="#cf222e"/>'
        for at in lost
    )
    said = (
        f"intervals between the {len(arrivals)} datagrams received (ms, up to {top * 1000:.1f})"
        f" over {end:.2f} s; {len(lost)} lost or withheld"
    )
    return (
        f'<figure><svg class="intervals" width="{WIDTH}" height="{HEIGHT}"'
        f' viewBox="0 0 {WIDTH} {HEIGHT}" role="img" aria-label="{said}">'
        f'<text x="0" y="12" font-size="10">{top * 1000:.1f} ms</text>'
        f'<text x="0" y="{HEIGHT - _BOTTOM}" font-size="10">0</text>'
        f'<line x1="{_LEFT}" x2="{WIDTH}" y1="{HEIGHT - _BOTTOM}" y2="{HEIGHT - _BOTTOM}"'
        ' stroke="#8c959f"/>'
        f'<text x="{_LEFT}" y="{HEIGHT - 2}" font-size="10">0 s</text>'
        f'<text x="{WIDTH - 40}" y="{HEIGHT - 2}" font-size="10">{end:.2f} s</text>'
        f'<polyline fill="none" stroke="#0969da" points="{points}"/>{ticks}</svg>'
        f"<figcaption>{said}</figcaption></figure>"
    )


def _skipped(entries: Sequence[Mapping[str, Any]]) -> list[float]:
    """The times of the data stream packets that came after a gap in the numbering, once for
    each number missing (a number that goes back is a reordering, not a loss)."""
    found: list[float] = []
    last: dict[str | None, int] = {}
    for entry in entries:
        if _gap(entry):
            last.clear()
        numbered = _SEQUENCE.search(entry["summary"]) if entry["direction"] == "received" else None
        if numbered is None:
            continue
        number = int(numbered[1])
        before = last.get(entry["source"])
        gap = (number - before - 1) % _NUMBERS if before is not None else 0
        if gap < _NUMBERS // 2:
            found += [entry["time"]] * gap
            last[entry["source"]] = number
    return found


def _arrival(entry: Mapping[str, Any]) -> bool:
    return bool(entry["transport"] == "udp" and entry["direction"] == "received")


def _gap(entry: Mapping[str, Any]) -> bool:
    """A note of what the transcript left out (lines, or a flow's payloads)."""
    return bool(entry["direction"] == "note" and LEFT_OUT in entry["summary"])


def _lost(entry: Mapping[str, Any]) -> bool:
    return bool(entry["direction"] == "withheld" or "by the impairment" in entry["summary"])
