"""rsp/session and rsp/motion cases that time the robot against its period T (D-RSP-13): its
UPLINKs at a T of more than a second, from HELLO and from PERIOD (R-RSP-42), and the stop of its
onLoss=zero effectors 25 periods into a silence, while the others hold (D-RSP-20; R-RSP-34,
R-RSP-36). The harness plays the local system.

Every other robot case runs at the model's T, tens of milliseconds; D-RSP-13 allows 5 ms to 10 s.
A robot whose clock goes wrong only at a slow T (a beat multiplied or raised by T where it should
be added to) still beats at a fast one."""

from __future__ import annotations

import itertools
from collections.abc import Callable, Mapping

from rcmlconf.conformance.context import Context
from rcmlconf.conformance.probes.held import margin, seen_by
from rcmlconf.conformance.probes.pace import ms, spaced
from rcmlconf.conformance.probes.rsp_datagram import SESSION_AT, Datagram, Where, newer, sequence_of
from rcmlconf.conformance.probes.rsp_devices import close_to, flags, reported, values_of
from rcmlconf.conformance.probes.rsp_driven import Driven, drive
from rcmlconf.conformance.probes.rsp_exchanges import must_take, reporting
from rcmlconf.conformance.probes.rsp_probe import RspProbe, open_probe
from rcmlconf.conformance.probes.rsp_raw import hand_driven
from rcmlconf.conformance.registry import case
from rcmlconf.conformance.roles import Role
from rcmlconf.conformance.rsp_numbers import (
    GAP_LONGEST,
    GAP_SHORTEST,
    LOST_PERIODS,
    STAMP_ROUNDING,
    STOP_LAG,
)
from rcmlconf.conformance.verdicts import Inconclusive
from rcmlconf.rsp.codec import PacketType
from rcmlconf.rsp.model import OnLoss
from rcmlconf.values import Value
from rcmlconf.values.shown import values_text

#: The slow T the cases ask for (ms): over a second, and three periods of it fit in a case.
SLOW_MS = 1200
#: UPLINKs a slow case watches: two gaps of T.
BEATS = 3
#: D-RSP-20: a stop is seen at most this many periods after the link is lost (the control period
#: to come round, then the UPLINK).
STOP_PERIODS = 2


def _slow_enough(period: float) -> None:
    """WELCOME may raise T (D-RSP-13): not so far that the case cannot watch it."""
    if period > 2 * SLOW_MS / 1000:
        raise Inconclusive(
            f"the robot raised T to {period * 1000:g} ms (D-RSP-13 lets it): {BEATS} periods"
            " of it do not fit in the case's time"
        )


async def _uplinks(probe: RspProbe, where: Where, until: float, count: int) -> list[Datagram]:
    """The first `count` UPLINKs received (so far, and until loop time `until`) for which
    `where` holds; fewer if no more came."""
    while True:
        found = [d for d in probe.packets(PacketType.UPLINK) if where(d)]
        if len(found) >= count or probe.now >= until:
            return found[:count]
        await probe.next(PacketType.UPLINK, wait=until - probe.now)


def _watched(probe: RspProbe, period: float) -> float:
    """How long `BEATS` UPLINKs may take from the first (or from a time before it): each as late
    after the one before as `spaced` lets it be, and the probe's quiet time for the harness."""
    return (BEATS - 1) * GAP_LONGEST * period + probe.quiet


async def _rested(probe: RspProbe, period: float, bye: Callable[[], object]) -> None:
    """End the session at the slow T (`bye` sends its BYE) and keep the robot a period of that T
    more before the pool gives it to another case: a robot may keep its control loop on the slow
    T's schedule until then (the reference does: the next session's sensors are read, and so
    reported, only at the tick that schedule left), and the other cases run at the model's T."""
    bye()
    await probe.listen(period + probe.quiet)


def _beating(ctx: Context, found: list[Datagram], period: float, note: str) -> None:
    """`found` are `BEATS` UPLINKs, each a period after the one before (R-RSP-42). Their number
    is no timing check: `_watched` leaves a second or more past the last. Nor is a gap too short
    by the robot's own timestamps: a loaded harness reads packets late, which the gaps of their
    arrivals (`spaced`, a timing check) show and the timestamps do not."""
    ctx.expect(
        len(found) >= BEATS,
        f"{BEATS} UPLINKs {period * 1000:g} ms apart{note}",
        f"{len(found)} UPLINKs",
        "R-RSP-42",
    )
    stamped = [
        (later.header.timestamp - earlier.header.timestamp) % (1 << 32)
        for earlier, later in itertools.pairwise(found)
    ]
    ctx.expect(
        all(gap >= GAP_SHORTEST * period * 1000 - STAMP_ROUNDING for gap in stamped),
        f"UPLINKs {period * 1000:g} ms apart by the robot's own clock{note}",
        f"timestamps (R-RSP-14) {', '.join(map(str, stamped))} ms apart",
        "R-RSP-42",
    )
    spaced(ctx, found, period, "UPLINKs", note=note)


@case(
    "rsp/session/slow-hello",
    f"A HELLO asking T = {SLOW_MS} ms: the robot reports a requested sensor every period",
    ["R-RSP-42", "R-RSP-23"],
    role=Role.ROBOT,
    timeout=8.0,
)
async def slow_hello(ctx: Context) -> None:
    probe = await open_probe(ctx)
    model = probe.model
    raw = hand_driven(probe, period_ms=SLOW_MS)
    await raw.open()
    period = raw.period  # WELCOME's
    _slow_enough(period)
    sensor = reported(model, 1)[0]
    try:
        # R-RSP-42: with a sensor to report, an UPLINK every T: the first within a period of the
        # request, and a period between each and the next.
        first = await must_take(
            ctx,
            probe,
            raw,
            flags(model, sensor),
            f"an UPLINK within a period ({period * 1000:g} ms) of the request for {sensor.name}",
            "R-RSP-42",
            wait=GAP_LONGEST * period + probe.quiet,
        )
        request = sequence_of(raw.last)
        found = await _uplinks(
            probe,
            lambda d: newer(d.header.last_received, request),
            first.at + _watched(probe, period),
            BEATS,
        )
        _beating(ctx, found, period, f" (T of WELCOME: {period * 1000:g} ms)")
        silent = [d for d in found if values_of(d, sensor) is None]
        ctx.expect(
            not silent,
            f"{sensor.name} in each UPLINK after its request",
            f"UPLINK #{silent[0].header.sequence} without it" if silent else "",
            "R-RSP-23",
        )
    finally:
        await _rested(probe, period, raw.bye)


@case(
    "rsp/session/slow-period",
    f"After a PERIOD of {SLOW_MS} ms the next UPLINK comes a new period after the last one, not"
    " at the old pace, and the UPLINKs go on every new period",
    ["R-RSP-42", "R-RSP-23"],
    role=Role.ROBOT,
    timeout=8.0,
)
async def slow_period(ctx: Context) -> None:
    probe, opened, sensor = await reporting(ctx)
    if await probe.state(sensor.name) is None:
        raise Inconclusive(f"no {sensor.name} at T = {opened.period * 1000:g} ms to start from")
    # WELCOME's T is what the robot raised HELLO's to: it may raise PERIOD's as well.
    period = max(SLOW_MS / 1000, opened.period)
    _slow_enough(period)
    spoiled = probe.spoiled
    change = probe.session.packets_sent % 65536  # the PERIOD's sequence number
    at = probe.now
    probe.session.set_period(SLOW_MS / 1000, at)
    probe.poke()  # the PERIOD goes at once

    def bye() -> None:
        probe.session.close(probe.now)
        probe.poke()

    try:
        if probe.spoiled > spoiled:
            raise Inconclusive("the impairment spoiled the first PERIOD")
        found = await _uplinks(
            probe,
            lambda d: newer(d.header.last_received, change),
            at + _watched(probe, period),
            BEATS - 1,
        )
        before = [
            d for d in probe.packets(PacketType.UPLINK) if not newer(d.header.last_received, change)
        ]
        if not before:
            raise Inconclusive(f"no UPLINK at T = {opened.period * 1000:g} ms before the PERIOD")
        # D-RSP-13: the robot's next UPLINK after PERIOD comes at the new pace: a new period after
        # the last it sent at the old one, not an old period after it.
        _beating(
            ctx,
            [before[-1], *found],
            period,
            f" (the last before the robot took PERIOD #{change}, then those after: the next"
            " UPLINK comes at the new pace, D-RSP-13)",
        )
    finally:
        await _rested(probe, period, bye)


# -- the motion filter --------------------------------------------------------------------------


@case(
    "rsp/motion/link-loss-stops",
    f"An onLoss=zero effector holds for {LOST_PERIODS} silent periods and is seen stopped within"
    f" {STOP_PERIODS} more",
    ["R-RSP-36", "R-RSP-34"],
    role=Role.ROBOT,
)
async def link_loss_stops(ctx: Context) -> None:
    driven = await drive(ctx, lambda e: e.on_loss is OnLoss.ZERO)
    probe, monitor, field = driven.probe, driven.monitor, driven.field
    period = driven.opened.period
    zero = field.zero()
    await driven.settled()
    start = probe.mark()
    probe.muted = True
    # D-RSP-26: seen stopped within D-RSP-20's 27 periods of the last packet we sent, and half a
    # second for the wire and the scheduling of the harness and the robot on a loaded machine.
    lag = STOP_LAG * ctx.scale
    bound = (LOST_PERIODS + STOP_PERIODS) * period + lag

    def stopped(found: Datagram) -> bool:
        values = values_of(found, monitor)
        return values is not None and close_to(field, values.get(field.name), zero)

    found = None
    # From the last datagram sent (the impairment's may leave after the mute), and past the bound
    # as long as only a long hold of the harness could hide the stop (`seen_by`).
    while found is None and probe.now < (end := probe.sent[-1][0] + bound + margin(ctx)):
        wait = end - probe.now
        found = await probe.next(PacketType.UPLINK, after=start, wait=wait, where=stopped)
    reports = [
        (d, values)
        for d in probe.packets(PacketType.UPLINK, after=start)
        if (values := values_of(d, monitor)) is not None
    ]
    moved = next(((d, v) for d, v in reports if not driven.at_wanted(v)), None)
    if moved is not None:
        _held(ctx, driven, moved)
    last = probe.sent[-1][0]
    seen_by(
        ctx,
        probe,
        found,
        last,
        last + bound,
        f"{monitor.name} at {values_text([field], {field.name: zero})[0]} within"
        f" {LOST_PERIODS}+{STOP_PERIODS} periods of the last DOWNLINK (D-RSP-20), and"
        f" {lag * 1000:.0f} ms for the harness (D-RSP-26): {bound * 1000:.0f} ms",
        "R-RSP-36",
        instead=f"still {driven.latest()}",
    )


def _held(ctx: Context, driven: Driven, moved: tuple[Datagram, Mapping[str, Value]]) -> None:
    """The first report of the monitor away from the value written came 25 periods or more after
    the robot heard our last packet: the one its UPLINK names (R-RSP-15), sent when we sent it,
    or the last we sent if it names none of ours. A report can only come later than the robot
    sent it, so a loaded harness makes this check no stricter."""
    probe, session_id, period = driven.probe, driven.opened.session_id, driven.opened.period
    found, values = moved
    heard = found.header.last_received
    ours = [
        at
        for at, data in probe.sent
        if int.from_bytes(data[SESSION_AT : SESSION_AT + 6]) == session_id
        and sequence_of(data) == heard
    ]
    silent = ours[-1] if ours else probe.sent[-1][0]
    held = found.at - silent
    ctx.expect(
        held >= LOST_PERIODS * period,
        f"{driven.monitor.name} held for {LOST_PERIODS} periods"
        f" ({LOST_PERIODS * period * 1000:g} ms) after the last packet the robot heard (#{heard})",
        f"{', '.join(values_text(driven.effector.fields, values))} after {ms([held])}",
        "R-RSP-34",
    )


@case(
    "rsp/motion/link-loss-holds",
    f"An onLoss=hold effector keeps its value through a silence of more than {LOST_PERIODS}"
    f"+{STOP_PERIODS} periods (only onLoss=zero ones stop)",
    ["R-RSP-36"],
    role=Role.ROBOT,
)
async def link_loss_holds(ctx: Context) -> None:
    driven = await drive(ctx, lambda e: e.on_loss is OnLoss.HOLD)
    probe, monitor = driven.probe, driven.monitor
    period = driven.opened.period
    await driven.settled()
    start, since = probe.mark(), probe.now
    probe.muted = True
    # Past where an onLoss=zero effector is seen stopped (D-RSP-26, rsp/motion/link-loss-stops's
    # bound), from the last datagram sent.
    lost = (LOST_PERIODS + STOP_PERIODS) * period + STOP_LAG * ctx.scale
    while probe.now < (end := probe.sent[-1][0] + lost):
        await probe.listen(end - probe.now)
    uplinks = probe.packets(PacketType.UPLINK, after=start)
    reports = [d for d in uplinks if values_of(d, monitor) is not None]
    if not reports or reports[-1].at < probe.sent[-1][0] + LOST_PERIODS * period:
        raise Inconclusive(f"no report of {monitor.name} once the link was lost")
    moved = await driven.moved(since)
    ctx.expect(
        moved is None,
        f"{monitor.name} holding {driven.wanted} while the link is lost (onLoss hold, D-RSP-20)",
        str(dict(moved)) if moved is not None else "",
    )
