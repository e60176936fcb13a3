"""Whether what must come by a bound came, as a harness whose event loop may be held up reads it
(D-RSP-26, D-RCTP-33). A hold of the loop delays what the harness reads by its length at most, so
it excuses a packet or a message read that much past its bound, and no more: one read later, or
none at all though the harness waited past the bound longer than it was held, is the peer's fault
however loaded the machine (a `timing` check of `Context.expect` would excuse any lateness once
the loop was held a little, and miss a peer that never sends)."""

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
    """How long the harness's loop was held (seconds) since loop time `since`, its holds added
    up: each delays what the harness reads by its length at most, and so do several, one after
    another, by their sum (a CPU-starved process is held many times a little, and a datagram
    waits for its turn through all of them). The embedded reference shares the loop: its sending
    was held as long."""
    return ctx.loop_watch.total(since) if ctx.loop_watch is not None else 0.0


def longest_hold(ctx: Context, since: float) -> float:
    """The longest single hold of the harness's loop (seconds) since loop time `since`: for a
    check whose slack only one hold that long could explain (a long watch sees many short ones)."""
    return ctx.loop_watch.held(since) if ctx.loop_watch is not None else 0.0


def came_by(
    ctx: Context, at: float, since: float, due: float, expected: str, requirement: str | None
) -> None:
    """What the case waited for from loop time `since`, read at loop time `at`, came by loop
    time `due`, as far as the harness's holds since `since` let it tell: Failed
    (`requirement`, `expected`) when it did not."""
    hold = held(ctx, since)
    ctx.expect(
        at <= due + hold,
        expected,
        f"after {at - since:.3f} s" + (f" (its loop held {hold:.3f} s)" if hold else ""),
        requirement,
    )


def never_came(
    ctx: Context,
    since: float,
    due: float,
    now: float,
    expected: str,
    requirement: str | None,
    instead: str = "",
) -> Failed | Inconclusive:
    """The verdict to raise when what the case waited for from loop time `since` until `now`
    did not come: Failed (`requirement`, `expected`), or Inconclusive while a hold of the
    harness's loop since `since` could hide it (the wait did not go that far past `due`).
    `instead` says what came."""
    hold = held(ctx, since)
    got = f"{instead or 'nothing'} within {now - since:.2f} s"
    if now < due + hold:
        return Inconclusive(
            f"expected {expected}; got {got}; but the harness's event loop was held"
            f" {hold * 1000:.0f} ms: it may have hidden it"
        )
    return Failed(ctx.requirement(requirement), expected, got)


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
    """`came_by` for a datagram `probe` waited for: `found`, or `never_came`."""
    if found is None:
        raise never_came(ctx, since, due, probe.now, expected, requirement, instead)
    came_by(ctx, found.at, since, due, expected, requirement)
    return found
