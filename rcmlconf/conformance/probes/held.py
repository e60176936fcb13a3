"""Whether something that must come by a bound came, allowing for holds of the harness's loop.

The harness's event loop may be held up (D-RSP-26, D-RCTP-33). A hold delays what the harness
reads by the hold's length at most. So a hold excuses a packet or message read up to that much
past its bound, and no more.

The peer is at fault, however loaded the machine, when:

- it was read later than its bound plus the holds; or
- it never came, though the harness waited past the bound for longer than the holds.

A plain `timing` check of `Context.expect` is too lenient here. One small hold would excuse any
lateness, and it would miss a peer that never sends.
"""

from __future__ import annotations

from rcmlconf.conformance.context import Context
from rcmlconf.conformance.probes.datagrams import DatagramLog
from rcmlconf.conformance.probes.rsp_datagram import Datagram
from rcmlconf.conformance.verdicts import Failed, Inconclusive

#: Seconds (times --timeout-scale) a case waits past a bound for what must come. Only a hold of
#: the harness's loop that long could hide it. A peer that keeps to the bound ends the wait early.
MARGIN = 1.0


def margin(ctx: Context) -> float:
    return MARGIN * ctx.scale


def held(ctx: Context, since: float) -> float:
    """How long the harness's loop was held since loop time `since`: all its holds added up.

    Each hold delays what the harness reads by its length at most. Several holds, one after
    another, delay it by their sum. A process short of CPU is held many times a little, and a
    datagram waits through all of them. The embedded reference shares the loop, so its sending
    was held as long. In seconds.
    """
    return ctx.loop_watch.total(since) if ctx.loop_watch is not None else 0.0


def longest_hold(ctx: Context, since: float) -> float:
    """The longest single hold of the harness's loop since loop time `since`, in seconds.

    It suits a check whose slack only one hold that long could explain. A sum would not do: a
    long watch sees many short holds.
    """
    return ctx.loop_watch.held(since) if ctx.loop_watch is not None else 0.0


def came_by(
    ctx: Context, at: float, since: float, due: float, expected: str, requirement: str | None
) -> None:
    """Fail unless what the case waited for came by loop time `due`.

    The case waited from loop time `since` and read it at loop time `at`. The holds of the
    harness's loop since `since` are added to `due`. When it came later, the case fails with
    `requirement` and `expected`.
    """
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
    """The verdict to raise when what the case waited for did not come.

    The case waited from loop time `since` until `now`. The verdict is Inconclusive if the wait
    did not go past `due` by the holds of the harness's loop since `since`: they could hide it.
    Otherwise it is Failed, with `requirement` and `expected`. `instead` says what came.
    """
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
    """`came_by` for a datagram that `probe` waited for. Returns `found`, or raises `never_came`."""
    if found is None:
        raise never_came(ctx, since, due, probe.now, expected, requirement, instead)
    came_by(ctx, found.at, since, due, expected, requirement)
    return found
