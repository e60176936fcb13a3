"""rsp/local, the pace: when an RSP local system under test sends, and at which T (D-RSP-13), the
harness playing its robot (`--role local`). Its session's packets begin as WELCOME is given, go on
every period through a silence of the robot that loses the link (the session ends only after
10 s), go on until its BYE ends the run (D-RSP-24 step 5), and the PERIOD it sends when the
scenario slows down (D-RSP-24 step 4) says the T it now keeps: twice the one in force (R-RSP-42,
R-RSP-43)."""

from __future__ import annotations

import itertools
import math

from rcmlconf.conformance.cases.rsp_local.session import (
    local_case,
    occurrence,
    played_model,
    session,
)
from rcmlconf.conformance.context import Context
from rcmlconf.conformance.probes.held import longest_hold, margin, seen_by
from rcmlconf.conformance.probes.local_probe import LocalProbe
from rcmlconf.conformance.probes.local_scenario import SCENARIO_LIFETIME
from rcmlconf.conformance.probes.pace import paced
from rcmlconf.conformance.probes.rsp_devices import first, of_kind
from rcmlconf.conformance.rsp_numbers import (
    GAP_LONGEST,
    KEEPALIVE_PERIODS,
    LOST_PERIODS,
    RESEND_LAG,
    SESSION_TIMEOUT,
)
from rcmlconf.conformance.verdicts import Inconclusive, NotApplicable
from rcmlconf.rsp.codec import PacketType, Period
from rcmlconf.rsp.codec.bodies import MAX_PERIOD_MS
from rcmlconf.rsp.model import DeviceKind

#: Periods rsp/local/lost-link-goes-on watches past the loss of the link.
WATCH = 10
#: rsp/local/period-doubles asks for a T this long at least (scaled): PERIOD carries T in whole
#: milliseconds, and a doubled T of hundreds of them shows a new T computed a hair off (a factor,
#: a rounding) that one of 40 ms would round away.
SLOW_PERIOD = 0.3


@local_case(
    "rsp/local/welcome-opens",
    "Once WELCOME is given, the local system's session begins: a DOWNLINK within 5 periods",
    ["R-RSP-42"],
)
async def welcome_opens(ctx: Context) -> None:
    probe = await session(ctx, used=False)
    period, since = probe.period, probe.now
    # D-RSP-12: the local system takes the WELCOME; D-RSP-13: from then on it sends a DOWNLINK
    # every T, or an empty one every 5 periods at least: D-RSP-26 judges such a gap to 1.6 of
    # 5 T, and the wire and the scheduling of both sides (RESEND_LAG); a hold of the harness's
    # loop excuses a DOWNLINK read that much later, and the case waits a margin past the bound.
    due = since + GAP_LONGEST * KEEPALIVE_PERIODS * period + RESEND_LAG * ctx.scale
    found = await probe.next(PacketType.DOWNLINK, after=0, wait=due + margin(ctx) - probe.now)
    hellos = len(probe.hellos)
    seen_by(
        ctx,
        probe,
        found,
        since,
        due,
        f"WELCOME taken (D-RSP-12): a DOWNLINK of session {probe.session_id:#x} within"
        f" {KEEPALIVE_PERIODS} periods of {period * 1000:g} ms (D-RSP-26: {due - since:.2f} s)",
        "R-RSP-42",
        instead=f"no DOWNLINK ({hellos} HELLO{'s' * (hellos > 1)} in all)",
    )


@local_case(
    "rsp/local/lost-link-goes-on",
    "Through a silence of the robot longer than 25 periods a DOWNLINK still goes every T",
    ["R-RSP-42"],
    timeout=7.0,
)
async def lost_link_goes_on(ctx: Context) -> None:
    model = played_model(ctx)
    # Nothing acknowledged and no keep-alive: after WELCOME the robot says nothing at all.
    reliable = of_kind(model, DeviceKind.COMMAND, DeviceKind.MEMORY_COMMAND)
    probe = await session(ctx, withheld=reliable, beating=False)
    period = probe.period
    watched = (LOST_PERIODS + WATCH) * period
    if watched > SESSION_TIMEOUT / 2:
        raise NotApplicable(
            f"at {model.name}'s T of {period * 1000:g} ms the link is lost only"
            f" {LOST_PERIODS * period:g} s into a silence (D-RSP-13), too near the session's"
            f" {SESSION_TIMEOUT:g} s timeout to watch it"
        )
    # From the robot's last word: a WELCOME sent again to a repeated HELLO moves it.
    while probe.now < (end := _last_word(probe) + watched):
        await probe.listen(end - probe.now)
    lost = _last_word(probe) + LOST_PERIODS * period
    # One period on: the local system's clock started when the WELCOME reached it.
    through = [d for d in probe.packets(PacketType.DOWNLINK) if d.at >= lost + period]
    paced(
        ctx,
        through,
        PacketType.DOWNLINK,
        period,
        f" from {LOST_PERIODS} periods into the robot's silence: the link is lost, the session"
        f" goes on until {SESSION_TIMEOUT:g} s of it (D-RSP-13)",
    )


def _last_word(probe: LocalProbe) -> float:
    """When the probe last sent the local system anything."""
    return probe.sent[-1][0]


@local_case(
    "rsp/local/period-doubles",
    "A memory event taken doubles T (D-RSP-24 step 4): each PERIOD says twice the T in force",
    ["R-RSP-43", "R-RSP-16"],
    timeout=6.0,
)
async def period_doubles(ctx: Context) -> None:
    model = played_model(ctx)
    memory = first(model, DeviceKind.MEMORY_EVENT)
    probe = await session(ctx, slower=math.ceil(SLOW_PERIOD * ctx.scale / model.period))
    in_force = round(probe.period * 1000)
    doubled = min(2 * in_force, MAX_PERIOD_MS)
    slower = doubled / 1000
    # R-RSP-43: a PERIOD in each of the three periods after the change, the first within one.
    change = await probe.answer_to(
        lambda: probe.uplink([occurrence(memory, 0)]), PacketType.PERIOD, wait=2 * slower
    )
    if change is None:
        raise Inconclusive(
            f"no PERIOD within {2 * slower * 1000:.0f} ms of {memory.name} #0 (D-RSP-24 step 4)"
        )
    await probe.listen(change.at + 3.5 * slower - probe.now)
    said = [
        d.body.period_ms for d in probe.packets(PacketType.PERIOD) if isinstance(d.body, Period)
    ]
    ctx.expect(
        all(ms == doubled for ms in said),
        f"PERIOD of {doubled} ms: twice WELCOME's {in_force} ms (at most {MAX_PERIOD_MS} ms)",
        f"PERIOD of {', '.join(map(str, said))} ms",
        "R-RSP-43",
    )


@local_case(
    "rsp/local/kept-until-bye",
    "The local system keeps its session until its BYE: never silent for 25 periods meanwhile",
    ["R-RSP-42"],
    timeout=SCENARIO_LIFETIME + 6.0,
)
async def kept_until_bye(ctx: Context) -> None:
    probe = await session(ctx, used=False)  # the robot beats and acknowledges all
    # R-RSP-42 wants a packet every 5 periods at least; every-period and idle-keep-alive time
    # that pace. This case watches a whole run for the session abandoned, a silence as long as
    # the robot takes for a lost link (D-RSP-13), which a loaded machine's stall of the local
    # system's process (unseen by the harness's loop) does not reach.
    silent = LOST_PERIODS * probe.period
    if silent > SCENARIO_LIFETIME / 4:
        raise NotApplicable(
            f"at a T of {probe.period * 1000:g} ms, {LOST_PERIODS} periods are over a quarter of"
            f" D-RSP-24's run ({SCENARIO_LIFETIME:g} s)"
        )
    opened = probe.opened_at
    assert opened is not None
    # D-RSP-12: a session ends by BYE or by the timeout (which this robot's beat never lets
    # come); until then R-RSP-42 holds. D-RSP-24 step 5 ends the run 10 s after WELCOME.
    end = opened + SCENARIO_LIFETIME + silent + probe.quiet
    bye = await probe.next(PacketType.BYE, after=0, wait=end - probe.now)
    ours = [
        d.at
        for d in probe.received
        if d.type is not PacketType.HELLO and (bye is None or d.at <= bye.at)
    ]
    marks = [opened, *ours, *([] if bye is not None else [probe.now])]
    since, until = max(itertools.pairwise(marks), key=lambda gap: gap[1] - gap[0])
    # Over a 10 s watch the harness's loop is often held a little (`timing=True` would excuse
    # any failure then); a hold delays what the harness reads by its length at most.
    held = longest_hold(ctx, since)
    ctx.expect(
        until - since < silent + held,
        f"a packet of session {probe.session_id:#x} at least every {KEEPALIVE_PERIODS} periods"
        f" until the local system's BYE (D-RSP-12: nothing else ends it), so never"
        f" {LOST_PERIODS} periods ({silent * 1000:g} ms) without one",
        f"nothing from {since - opened:.2f} s to {until - opened:.2f} s after WELCOME"
        + ("" if bye is not None else ", and no BYE")
        + (f" (the harness's loop held {held * 1000:.0f} ms at most)" if held else ""),
    )
    if bye is None:
        raise Inconclusive(
            f"no BYE {SCENARIO_LIFETIME:g} s after WELCOME: the run's end (D-RSP-24 step 5) did"
            " not come; the session was kept meanwhile"
        )
