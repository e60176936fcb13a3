"""`rcmlconf dissect --plot FILE.png`: inter-arrival time and latency over time, per stream.

Latency is the one-way transit (arrival minus the sender's timestamp) less the stream's smallest,
in milliseconds: the delay each packet had beyond the quickest one's, which needs no clock
synchronisation (RFC 3550's relative transit time). matplotlib is imported here only, and only
`--plot` imports this module (it comes with the `plot` extra).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from rcmlconf.dissect.records import LABELS
from rcmlconf.dissect.streams import Stream
from rcmlconf.wording import plural

#: Streams drawn, at most: the ones with the most packets.
MAX_STREAMS = 8


def plot_streams(streams: Sequence[Stream], path: Path, title: str) -> int:
    """Draw the streams with a time series of two packets or more; how many were drawn."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    drawn = [s for s in streams if s.series is not None and len(s.series[0]) >= 1]
    drawn.sort(key=lambda s: s.packets, reverse=True)
    left_out = len(drawn) - MAX_STREAMS
    drawn = drawn[:MAX_STREAMS]
    rows = max(len(drawn), 1)
    figure, axes = plt.subplots(rows, 2, figsize=(12, 2.6 * rows + 0.8), squeeze=False)
    start = min((s.first for s in drawn), default=0.0)
    for row, stream in enumerate(drawn):
        assert stream.series is not None
        times, gaps, transits = stream.series
        seconds = [t - start for t in times]
        fastest = min(transits)
        name = (
            f"{LABELS[stream.protocol]} {stream.source} → {stream.destination} ({stream.session})"
        )
        left, right = axes[row]
        left.plot(seconds, [g * 1000 for g in gaps], ".", markersize=1.5)
        left.set_ylabel("inter-arrival (ms)")
        left.set_title(name, fontsize=8, loc="left")
        right.plot(
            seconds,
            [(t - fastest) * 1000 for t in transits],
            ".",
            markersize=1.5,
            color="tab:orange",
        )
        right.set_ylabel("latency beyond the fastest (ms)")
        right.set_title(f"jitter {stream.jitter * 1000:.3f} ms (RFC 3550)", fontsize=8, loc="left")
        for axis in (left, right):
            axis.grid(True, alpha=0.3)
            if row == rows - 1:
                axis.set_xlabel("seconds from the first packet")
    if not drawn:
        axes[0][0].text(0.5, 0.5, "no stream of two packets or more", ha="center")
    suffix = f" ({plural(left_out, 'more stream')} not drawn)" if left_out > 0 else ""
    figure.suptitle(f"{title}{suffix}", fontsize=10)
    figure.tight_layout()
    # PNG whatever the name's suffix: matplotlib would take it for the format, or add .png.
    figure.savefig(path, dpi=100, format="png")
    plt.close(figure)
    return len(drawn)
