"""The pace of the RSP datagrams a case received, whichever side the harness plays: a packet every
period (D-RSP-13), or repeats a fixed interval apart (D-RSP-12's HELLO, the keep-alive). The gaps
are read off the harness's clock: each check is a `timing` one (`Context.expect`), inconclusive
rather than failed while the harness's event loop was held, as far as the holds explain it. A
hold delays what the harness reads and adds no packet: packets too many for the span they were
read in (`crowded`) take holds as long as sending them would take longer (D-RSP-26)."""

from __future__ import annotations

import itertools
import math
import statistics
from collections.abc import Iterable, Sequence

from rcmlconf.conformance.context import Context, outside_bounds
from rcmlconf.conformance.probes.rsp_datagram import Datagram
from rcmlconf.conformance.rsp_numbers import GAP_LONGEST, GAP_SHORTEST
from rcmlconf.rsp.codec import PacketType

#: Durations a failure's text shows at most, from the first and from the last.
SHOWN = 20


def ms(seconds: Iterable[float]) -> str:
    """Durations in milliseconds, for a failure's text (the first and the last SHOWN of many)."""
    shown = [f"{s * 1000:.0f}" for s in seconds]
    if len(shown) > 2 * SHOWN:
        shown[SHOWN:-SHOWN] = [f"... ({len(shown) - 2 * SHOWN} more)"]
    return ", ".join(shown) + " ms"


def gaps(found: Sequence[Datagram]) -> list[float]:
    """The seconds between the arrivals of consecutive datagrams."""
    return [b.at - a.at for a, b in itertools.pairwise(found)]


def crowded(found: Sequence[Datagram], gaps: int, shortest: float) -> float:
    """Seconds more than the span `found` were read in that a side needs to send them with `gaps`
    of their gaps `shortest` long at least (0 if none): what only holds of the harness's loop as
    long can have crowded them into that span (D-RSP-26)."""
    span = found[-1].at - found[0].at if found else 0.0
    return max(gaps * shortest - span, 0.0)


def paced(
    ctx: Context,
    found: Sequence[Datagram],
    kind: PacketType,
    period: float,
    note: str = "",
    requirement: str = "R-RSP-42",
) -> None:
    """`found`, packets of `kind`, came one every `period`: five at least, their median gap
    within 0.7 to 1.4 periods (D-RSP-13's bounds; one packet the harness read late does not move
    the median);
    `note` follows the expected pace in the failure's text."""
    name = kind.name
    article = "an" if name[0] in "AEIOU" else "a"
    between = gaps(found)
    ctx.expect(
        len(between) >= 4,
        f"{article} {name} every period",
        f"{len(found)} {name}s",
        requirement,
        timing=True,
    )
    median = statistics.median(between)
    low, high = 0.7 * period, 1.4 * period
    # A median of `low` or more: half the gaps that long at least, as the side sent them.
    by = max(outside_bounds(median, low, high), crowded(found, math.ceil(len(between) / 2), low))
    ctx.expect(
        low <= median <= high,
        f"{name}s {period * 1000:g} ms apart{note}",
        f"a median of {median * 1000:.1f} ms between {len(found)} {name}s",
        requirement,
        timing=True,
        by=by,
    )


def spaced(
    ctx: Context,
    found: Sequence[Datagram],
    interval: float,
    what: str,
    requirement: str = "R-RSP-42",
    *,
    note: str = "",
) -> None:
    """Each of `found` (`what`, in the failure's text) came `interval` after the one before,
    within 0.6 to 1.6 intervals (D-RSP-13's bounds)."""
    between = gaps(found)
    low, high = GAP_SHORTEST * interval, GAP_LONGEST * interval
    widest = max((outside_bounds(gap, low, high) for gap in between), default=0.0)
    ctx.expect(
        all(low <= gap <= high for gap in between),
        f"{what} {interval * 1000:g} ms apart{note}",
        ms(between),
        requirement,
        timing=True,
        by=max(widest, crowded(found, len(between), low)),
    )
