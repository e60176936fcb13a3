"""The pace of the RSP datagrams a case received, whichever side the harness plays: a packet every
period (D-RSP-13), or repeats a fixed interval apart (D-RSP-12's HELLO, the keep-alive). The gaps
are read off the harness's clock: each check is a `timing` one (`Context.expect`), inconclusive
rather than failed while the harness's event loop was held."""

from __future__ import annotations

import itertools
import statistics
from collections.abc import Iterable, Sequence

from rcmlconf.conformance.context import Context, outside_bounds
from rcmlconf.conformance.probes.rsp_datagram import Datagram
from rcmlconf.conformance.rsp_numbers import GAP_LONGEST, GAP_SHORTEST
from rcmlconf.rsp.codec import PacketType


def ms(seconds: Iterable[float]) -> str:
    """Durations in milliseconds, for a failure's text."""
    return ", ".join(f"{s * 1000:.0f}" for s in seconds) + " ms"


def gaps(found: Sequence[Datagram]) -> list[float]:
    """The seconds between the arrivals of consecutive datagrams."""
    return [b.at - a.at for a, b in itertools.pairwise(found)]


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
    ctx.expect(
        0.7 * period <= median <= 1.4 * period,
        f"{name}s {period * 1000:g} ms apart{note}",
        f"a median of {median * 1000:.1f} ms between {len(found)} {name}s",
        requirement,
        timing=True,
        by=outside_bounds(median, 0.7 * period, 1.4 * period),
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
    ctx.expect(
        all(low <= gap <= high for gap in between),
        f"{what} {interval * 1000:g} ms apart{note}",
        ms(between),
        requirement,
        timing=True,
        by=max((outside_bounds(gap, low, high) for gap in between), default=0.0),
    )
