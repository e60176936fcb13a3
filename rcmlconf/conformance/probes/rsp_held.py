"""Whether a packet that must come by a bound came, as a harness whose event loop may be held up
reads it (D-RSP-26). A hold of the loop delays what the harness reads by its length at most, so
it excuses a packet read that much past its bound, and no more: a packet read later, or none at
all though the harness waited past the bound longer than it was held, is the peer's fault however
loaded the machine (a `timing` check of `Context.expect` would excuse any lateness once the loop
was held a little, and miss a peer that never sends)."""

from __future__ import annotations

from rcmlconf.conformance.context import Context
from rcmlconf.conformance.probes.datagrams import DatagramLog
from rcmlconf.conformance.probes.rsp_datagram import Datagram
from rcmlconf.conformance.verdicts import Failed, Inconclusive

#: Seconds (times --timeout-scale) a case waits past a bound for what must come: only a hold of
#: the harness's loop that long could hide it. A peer that keeps to the bound ends the wait early.
MARGIN = 1.0


def margin(ctx: Context) -> float:
    return MARGIN * ctx.scale


def held(ctx: Context, since: float) -> float:
    """The longest the harness's loop was held (seconds) since loop time `since`."""
    return ctx.loop_watch.held(since) if ctx.loop_watch is not None else 0.0


def seen_by(
    ctx: Context,
    probe: DatagramLog,
    found: Datagram | None,
    since: float,
    due: float,
    expected: str,
    requirement: str | None = None,
    *,
    instead: str = "",
) -> Datagram:
    """`found`, what the case waited for from loop time `since` until now, came by loop time
    `due`, as far as the harness's holds since `since` let it tell; Failed (`requirement`,
    `expected`) when it did not, Inconclusive when a hold could hide it. `instead` says what came
    instead of it, if nothing did."""
    hold = held(ctx, since)
    if found is not None:
        ctx.expect(
            found.at <= due + hold,
            expected,
            f"after {found.at - since:.3f} s" + (f" (its loop held {hold:.3f} s)" if hold else ""),
            requirement,
        )
        return found
    got = f"{instead or 'nothing'} within {probe.now - since:.2f} s"
    if probe.now < due + hold:
        raise Inconclusive(
            f"expected {expected}; got {got}; but the harness's event loop was held"
            f" {hold * 1000:.0f} ms: it may have hidden it"
        )
    raise Failed(ctx.requirement(requirement), expected, got)
