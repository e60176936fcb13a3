"""rsp/event, memory events: the robot sends an unacknowledged memory event again after each
retransmission timeout, and not sooner (R-RSP-28), and a device's next one only once the one
before is acknowledged (R-RSP-29). The timeout is D-RSP-17's: 10 T before a round trip is measured,
3 R after the first round trip R, at least 2 T, at most 2 s, doubled after each retransmission;
each case reaches one part of it. The harness plays the local system and acknowledges only when
it says (`probes.rsp_raised`).

"Not sooner" is judged on the robot's own timestamps, "after" within D-RSP-26's bound read off
the harness's clock (`seen_by`: as far as its loop's holds let it tell). Out of reach: the
smoothing of several round trips (SRTT and RTTVAR after the first), which would need a case to
see several memory events acknowledged in a row, a second apiece (D-RSP-25), before the one it
times.
"""

from __future__ import annotations

from collections.abc import Sequence

from rcmlconf.conformance.context import Context
from rcmlconf.conformance.probes.held import margin, seen_by
from rcmlconf.conformance.probes.rsp_datagram import Datagram, newer, summary
from rcmlconf.conformance.probes.rsp_probe import RspProbe
from rcmlconf.conformance.probes.rsp_raised import (
    OCCURS_WITHIN,
    ack,
    carrying,
    elapsed_ms,
    id_space,
    memory_event_raised,
    missing,
    received_uplinks,
    watch,
)
from rcmlconf.conformance.registry import case
from rcmlconf.conformance.roles import Role
from rcmlconf.conformance.rsp_numbers import (
    MAX_RTO,
    STAMP_ROUNDING,
    measured_rto,
    resent_within,
    unmeasured_rto,
)
from rcmlconf.conformance.verdicts import Inconclusive
from rcmlconf.rsp.model import Device

#: Retransmissions a case times: the first after the first timeout, the second after it doubled.
RESENDS = 2
#: How long the memory-event case withholds its ACK to leave the robot a second occurrence to hold
#: back (R-RSP-29), seconds.
HOLD = 1.3
#: rsp/event/memory-event-rto-ceiling's T (ms): 10 T is twice D-RSP-17's 2 s ceiling.
SLOW_MS = 400
#: rsp/event/memory-event-rto-measured holds its first ACK this many periods: a round trip that
#: makes the next timeout (3 R) half as long again as 10 T, and leaves the first one (10 T) time
#: to spare before a retransmission would spoil the measurement (Karn's rule).
HELD_PERIODS = 5


def _one_at_a_time(ctx: Context, uplinks: Sequence[Datagram], found: Device, ident: int) -> None:
    """R-RSP-29: no other occurrence of `found` while `ident` waits for its ACK."""
    others = [(u, i) for u, i in carrying(uplinks, found) if i != ident]
    ctx.expect(
        not others,
        f"no other {found.name} before #{ident} is acknowledged",
        ", ".join(f"#{i} in UPLINK #{u.header.sequence}" for u, i in others),
        "R-RSP-29",
    )


async def _sent_again(
    ctx: Context,
    probe: RspProbe,
    memory: Device,
    ident: int,
    last: Datagram,
    period: float,
    timeouts: tuple[float, float],
    why: str,
) -> Datagram:
    """`memory` #`ident`'s next send after UPLINK `last`, no ACK given: no sooner than the
    shortest of `timeouts` (seconds, `why` says whose) by the robot's own stamps, and seen within
    D-RSP-26's bound of the longest, read off the harness's clock."""
    shortest, longest = timeouts
    within = resent_within(longest, period, ctx.scale)
    found_in = await watch(
        probe,
        probe.received.index(last) + 1,
        last.at + within + margin(ctx) - probe.now,
        lambda u: any(i == ident for _, i in carrying(u, memory)),
    )
    _one_at_a_time(ctx, found_in, memory, ident)
    again = next((u for u, i in carrying(found_in, memory) if i == ident), None)
    if missing(probe, last, again or probe.received[-1]):
        raise Inconclusive(
            f"packets of the robot's were lost after UPLINK #{last.header.sequence}:"
            f" {memory.name} #{ident} may have been sent again in one of them"
        )
    expected = (
        f"{memory.name} #{ident} sent again {longest * 1000:.0f} ms at most after UPLINK"
        f" #{last.header.sequence} ({why}, no ACK sent; D-RSP-26: seen within"
        f" {within * 1000:.0f} ms)"
    )
    again = seen_by(ctx, probe, again, last.at, last.at + within, expected, "R-RSP-28")
    elapsed = elapsed_ms(last, again)
    ctx.expect(
        elapsed >= shortest * 1000 - STAMP_ROUNDING,
        f"{memory.name} #{ident} sent again no sooner than {shortest * 1000:.0f} ms ({why})",
        f"{elapsed} ms after, by its stamps (UPLINK #{last.header.sequence} at"
        f" {last.header.timestamp} ms, #{again.header.sequence} at {again.header.timestamp} ms)",
        "R-RSP-28",
    )
    return again


async def _unmeasured(ctx: Context, period_ms: int | None = None) -> None:
    """A memory event left unacknowledged: sent again after 10 T, then after twice that, each at
    most 2 s (D-RSP-17: no round trip measured), in a session at `period_ms`; acknowledged, sent
    no more."""
    probe, raw, memory, sent, ident = await memory_event_raised(ctx, period_ms=period_ms)
    period = raw.period
    begun = probe.received.index(sent)
    sends = [sent]
    for retransmission in range(RESENDS):
        rto = unmeasured_rto(period, retransmission)
        why = f"retransmission {retransmission + 1}: 10 T, doubled after each, at most 2 s"
        again = await _sent_again(ctx, probe, memory, ident, sends[-1], period, (rto, rto), why)
        sends.append(again)
    _, acked = ack(raw, memory, ident)
    acked_at = probe.now
    # As long as the next retransmission could come (D-RSP-26).
    wait = resent_within(unmeasured_rto(period, RESENDS), period, ctx.scale)
    await probe.listen(max(0.0, sends[-1].at + wait - acked_at))
    late = [
        u
        for u, i in carrying(received_uplinks(probe, begun), memory)
        if i == ident and newer(u.header.last_received, acked)
    ]
    ctx.expect(
        not late,
        f"no more {memory.name} #{ident} once the robot has its ACKs (up to #{acked})",
        ", ".join(summary(probe.model, u.header, u.body) for u in late),
        "R-RSP-28",
    )


@case(
    "rsp/event/memory-event-resent",
    "An unacknowledged memory event is sent again after each retransmission timeout, not sooner,"
    " and no more once acknowledged",
    ["R-RSP-28", "R-RSP-29"],
    role=Role.ROBOT,
    timeout=6.0,
)
async def memory_event_resent(ctx: Context) -> None:
    await _unmeasured(ctx)


@case(
    "rsp/event/memory-event-rto-ceiling",
    f"At a T of {SLOW_MS} ms an unacknowledged memory event is sent again after 2 s each time, not"
    " 10 T or twice that (the timeout's ceiling)",
    ["R-RSP-28"],
    role=Role.ROBOT,
    timeout=12.0,
)
async def memory_event_rto_ceiling(ctx: Context) -> None:
    await _unmeasured(ctx, SLOW_MS)


async def _measured(ctx: Context, held_periods: int) -> None:
    """Memory event #n acknowledged `held_periods` periods after the harness read it: one round
    trip measured (D-RSP-17); #n+1, left unacknowledged, then goes again after 3 R within the
    timeout's bounds (D-RSP-26 bounds R)."""
    probe, raw, memory, sent, ident = await memory_event_raised(ctx)
    period = raw.period
    await probe.listen(held_periods * period)
    first_ack, _ = ack(raw, memory, ident)
    held = probe.now - sent.at
    seconds = OCCURS_WITHIN * ctx.scale
    found_in = await watch(
        probe,
        probe.received.index(sent) + 1,
        seconds,
        lambda u: any(i != ident for _, i in carrying(u, memory)),
    )
    following = next(((u, i) for u, i in carrying(found_in, memory) if i != ident), None)
    if following is None:
        raise Inconclusive(f"the robot raised no second {memory.name} within {seconds:.2g} s")
    uplink, second = following
    if any(
        i == ident and not newer(u.header.last_received, first_ack)
        for u, i in carrying(found_in, memory)
    ):
        raise Inconclusive(
            f"{memory.name} #{ident} went again before the robot had its ACK, held"
            f" {held * 1000:.0f} ms: no round trip measured (Karn's rule)"
        )
    why = (
        f"D-RSP-17 after one round trip of {held * 1000:.0f} ms or more: 3 R, at least 2 T, at"
        f" most {MAX_RTO:g} s"
    )
    timeouts = measured_rto(held, period)
    await _sent_again(ctx, probe, memory, second, uplink, period, timeouts, why)
    ack(raw, memory, second)


@case(
    "rsp/event/memory-event-rto-floor",
    "After a memory event acknowledged at once the next is sent again no sooner than 2 T (the"
    " timeout's floor)",
    ["R-RSP-28"],
    role=Role.ROBOT,
    timeout=7.0,
)
async def memory_event_rto_floor(ctx: Context) -> None:
    await _measured(ctx, 0)


@case(
    "rsp/event/memory-event-rto-measured",
    f"After a memory event acknowledged {HELD_PERIODS} periods late the next is sent again after"
    " 3 times that round trip, not 10 T",
    ["R-RSP-28"],
    role=Role.ROBOT,
    timeout=7.0,
)
async def memory_event_rto_measured(ctx: Context) -> None:
    await _measured(ctx, HELD_PERIODS)


@case(
    "rsp/event/memory-event-waits",
    "A device's next memory event goes only once the one before is acknowledged, with the next ID",
    ["R-RSP-29", "R-RSP-24"],
    role=Role.ROBOT,
    timeout=7.0,
)
async def memory_event_waits(ctx: Context) -> None:
    probe, raw, memory, sent, ident = await memory_event_raised(ctx)
    ctx.expect(
        ident == 0, f"{memory.name} #0 first in the session (D-RSP-5)", f"#{ident}", "R-RSP-24"
    )
    begun = probe.received.index(sent)
    await probe.listen(HOLD * ctx.scale)
    _one_at_a_time(ctx, received_uplinks(probe, begun), memory, ident)
    acked, _ = ack(raw, memory, ident)
    after = probe.mark()
    following = (ident + 1) % id_space(probe.model)
    seconds = OCCURS_WITHIN * ctx.scale
    found_in = await watch(
        probe, after, seconds, lambda u: any(i != ident for _, i in carrying(u, memory))
    )
    nxt = next(((u, i) for u, i in carrying(found_in, memory) if i != ident), None)
    if nxt is None:
        raise Inconclusive(
            f"the robot raised no second {memory.name} within {HOLD * ctx.scale + seconds:.2g} s"
            " of the first, so none was held back"
        )
    uplink, second = nxt
    ctx.expect(
        newer(uplink.header.last_received, acked),
        f"{memory.name} #{second} sent after the robot could have its ACK (#{acked} on)",
        f"in UPLINK #{uplink.header.sequence}, which has received up to"
        f" #{uplink.header.last_received}",
        "R-RSP-29",
    )
    ctx.expect(
        second == following,
        f"{memory.name} #{following}: one more than #{ident}",
        f"#{second}",
        "R-RSP-24",
    )
    ack(raw, memory, second)
