"""rsp/event: the events a robot raises. The harness plays the local system.

- Events ride the three UPLINKs after they occur (D-RSP-17, R-RSP-30).
- Occurrences are numbered 0, 1, 2, ... per device, and repeated with their ID (D-RSP-5,
  R-RSP-24).
- Nothing is reported of a device that was not requested (D-RSP-14, R-RSP-23).
- An unacknowledged memory event is sent again after each retransmission timeout, and not
  sooner (R-RSP-28). A device's next one waits until the one before is acknowledged (R-RSP-29).

How the harness waits for what the robot raises is in `probes.rsp_raised`.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from rcmlconf.conformance.context import Context
from rcmlconf.conformance.probes.held import margin, seen_by
from rcmlconf.conformance.probes.rsp_datagram import Datagram, newer, summary
from rcmlconf.conformance.probes.rsp_devices import (
    flags,
    of_kind,
    reported,
)
from rcmlconf.conformance.probes.rsp_probe import RspProbe
from rcmlconf.conformance.probes.rsp_raised import (
    OCCURS_WITHIN,
    ack,
    carrying,
    elapsed_ms,
    id_space,
    memory_event_raised,
    missing,
    nothing_raised,
    received_uplinks,
    requesting,
    watch,
)
from rcmlconf.conformance.probes.rsp_raw import RawSession
from rcmlconf.conformance.registry import case
from rcmlconf.conformance.roles import Role
from rcmlconf.conformance.rsp_numbers import (
    MAX_RTO,
    STAMP_ROUNDING,
    measured_rto,
    resent_within,
    unmeasured_rto,
)
from rcmlconf.conformance.verdicts import Inconclusive, NotApplicable
from rcmlconf.rsp.model import Device, DeviceKind, RobotModel
from rcmlconf.values import Value

#: D-RSP-17: an event rides this many UPLINKs.
RIDES = 3


# -- events: what the UPLINKs carry --------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class _Run:
    """One device's items with one ID in consecutive carrying UPLINKs: an occurrence and its
    repeats, as the local system sees them."""

    device: Device
    id: int
    #: The indices, among the UPLINKs watched, of those carrying it.
    uplinks: tuple[int, ...]
    #: The fields of each.
    values: tuple[dict[str, Value], ...]


def _runs(model: RobotModel, uplinks: Sequence[Datagram], kinds: set[DeviceKind]) -> list[_Run]:
    """Each device's occurrences in `uplinks`, in order: a run ends where the device's next item
    has another ID."""
    runs: list[_Run] = []
    open_runs: dict[int, _Run] = {}
    for index, uplink in enumerate(uplinks):
        for item in uplink.items:
            found = model.devices[item.device]
            if found.kind not in kinds or item.id is None:
                continue
            values = dict(item.values or {})
            last = open_runs.get(item.device)
            if last is not None and last.id == item.id:
                grown = _Run(found, item.id, (*last.uplinks, index), (*last.values, values))
                runs[runs.index(last)] = grown
                open_runs[item.device] = grown
            else:
                run = _Run(found, item.id, (index,), (values,))
                runs.append(run)
                open_runs[item.device] = run
    return runs


def _complete(run: _Run, uplinks: Sequence[Datagram]) -> bool:
    """An UPLINK came after the run's last: it is over (or it would have ridden that one)."""
    return run.uplinks[-1] + 1 < len(uplinks)


def _judged(probe: RspProbe, run: _Run, uplinks: Sequence[Datagram]) -> bool:
    """The run is over and no packet of the robot's was lost from the UPLINK before it to the
    one after it: how many UPLINKs carried it is known."""
    first, last = run.uplinks[0], run.uplinks[-1]
    return (
        first > 0
        and _complete(run, uplinks)
        and not missing(probe, uplinks[first - 1], uplinks[last + 1])
    )


def _events(model: RobotModel) -> list[Device]:
    found = of_kind(model, DeviceKind.EVENT)
    if not found:
        raise NotApplicable(f"{model.name} has no event")
    return found


@dataclass(frozen=True, slots=True)
class _Raised:
    """The events a session requesting every event device saw the robot raise."""

    probe: RspProbe
    raw: RawSession
    #: The UPLINKs watched, each once, in the robot's order (`_uplinks`).
    uplinks: list[Datagram]
    #: The events' runs in them (never empty).
    runs: list[_Run]
    #: How long the case watched at the most.
    seconds: float


async def _events_raised(
    ctx: Context, enough: Callable[[RspProbe, list[Datagram], list[_Run]], bool]
) -> _Raised:
    """A session requesting every event device, watched until `enough` holds of the probe, the
    UPLINKs received and the events' runs in them, or OCCURS_WITHIN has passed; Inconclusive if
    the robot raised no event."""
    model = ctx.target.rsp_model
    events = _events(model) if model is not None else []
    probe, raw = await requesting(ctx, *events)
    start = probe.mark()
    kinds = {DeviceKind.EVENT}
    seconds = OCCURS_WITHIN * ctx.scale
    uplinks = await watch(
        probe, start, seconds, lambda u: enough(probe, u, _runs(probe.model, u, kinds))
    )
    runs = _runs(probe.model, uplinks, kinds)
    if not runs:
        raise nothing_raised("event", seconds)
    return _Raised(probe, raw, uplinks, runs, seconds)


def _same_values(ctx: Context, run: _Run) -> None:
    """R-RSP-24: an occurrence is repeated with its ID and its fields; other fields under the
    same ID are another occurrence numbered like the one before."""
    distinct = [v for i, v in enumerate(run.values) if v not in run.values[:i]]
    ctx.expect(
        len(distinct) == 1,
        f"{run.device.name} #{run.id} repeated with its fields {run.values[0]}",
        f"#{run.id} carried {distinct} in consecutive UPLINKs: new occurrences under one ID",
        "R-RSP-24",
    )


@case(
    "rsp/event/three-uplinks",
    "An event rides exactly the three UPLINKs after it occurs, with its ID and fields each time",
    ["R-RSP-30", "R-RSP-24"],
    role=Role.ROBOT,
    timeout=6.0,
)
async def three_uplinks(ctx: Context) -> None:
    def enough(probe: RspProbe, uplinks: list[Datagram], runs: list[_Run]) -> bool:
        return sum(_judged(probe, r, uplinks) for r in runs) >= 3

    raised = await _events_raised(ctx, enough)
    uplinks = raised.uplinks
    done = [r for r in raised.runs if _judged(raised.probe, r, uplinks)]
    if not done:
        raise Inconclusive(f"{len(raised.runs)} events, each next to a lost UPLINK or still riding")
    for run in done:
        _same_values(ctx, run)
        rode = run.uplinks
        ctx.expect(
            len(rode) == RIDES and rode[-1] - rode[0] == RIDES - 1,
            f"{run.device.name} #{run.id} in {RIDES} consecutive UPLINKs, then no more",
            f"in {len(rode)} UPLINKs: "
            + ", ".join(f"#{uplinks[i].header.sequence}" for i in rode)
            + f" (of #{uplinks[rode[0]].header.sequence} to #{uplinks[rode[-1]].header.sequence})",
            "R-RSP-30",
        )


@case(
    "rsp/event/ids-count",
    "Each event device's occurrences are numbered 0, 1, 2, ... in the session, a repeat by its ID",
    ["R-RSP-24"],
    role=Role.ROBOT,
    timeout=6.0,
)
async def ids_count(ctx: Context) -> None:
    def enough(_: RspProbe, uplinks: list[Datagram], runs: list[_Run]) -> bool:
        counts: dict[int, int] = {}
        for run in runs:
            if _complete(run, uplinks):
                counts[run.device.position] = counts.get(run.device.position, 0) + 1
        return max(counts.values(), default=0) >= 3

    raised = await _events_raised(ctx, enough)
    probe, uplinks = raised.probe, raised.uplinks
    space = id_space(probe.model)
    numbered: dict[str, list[_Run]] = {}
    for run in raised.runs:
        _same_values(ctx, run)
        numbered.setdefault(run.device.name, []).append(run)
    welcome = raised.raw.welcome
    assert welcome is not None
    for name, found in numbered.items():
        ids = [run.id for run in found]
        wanted = [n % space for n in range(len(ids))]
        # Only where no packet was lost: all three rides of an occurrence may have been.
        first = uplinks[found[0].uplinks[0]]
        skips = [
            (a.id, b.id)
            for a, b in itertools.pairwise(found)
            if b.id != (a.id + 1) % space
            and not missing(probe, uplinks[a.uplinks[-1]], uplinks[b.uplinks[0]])
        ]
        ctx.expect(
            (ids[0] == 0 or missing(probe, welcome, first)) and not skips,
            f"{name}'s occurrences numbered {wanted} (D-RSP-5: from 0, one more each)",
            f"{ids}",
        )
    if max(len(runs) for runs in numbered.values()) < 2:
        raise Inconclusive(
            f"the robot raised one event a device within {raised.seconds:.2g} s"
            f" ({', '.join(numbered)}): no second ID to check"
        )


@case(
    "rsp/event/unrequested",
    "No event or memory event of a device the DOWNLINKs do not request is reported",
    ["R-RSP-23"],
    role=Role.ROBOT,
    timeout=6.0,
)
async def unrequested(ctx: Context) -> None:
    model = ctx.target.rsp_model
    if model is None:
        raise NotApplicable("the RSP robot's model is not known (give --rsp-model)")
    raised = of_kind(model, DeviceKind.EVENT, DeviceKind.MEMORY_EVENT)
    if not raised:
        raise NotApplicable(f"{model.name} has no event or memory event")
    sensor = reported(model, 1)[0]
    probe, raw = await requesting(ctx, sensor)  # UPLINKs every period, no occurrence asked for
    start = probe.mark()
    kinds = {DeviceKind.EVENT, DeviceKind.MEMORY_EVENT}
    await probe.listen(OCCURS_WITHIN / 2 * ctx.scale)
    stray = _runs(model, received_uplinks(probe, start), kinds)
    ctx.expect(
        not stray,
        "no event or memory event: none requested (D-RSP-14)",
        ", ".join(f"{r.device.name} #{r.id}" for r in stray),
    )
    if not received_uplinks(probe, start):
        raise Inconclusive(f"no UPLINK reporting the requested {sensor.name}")
    asked = probe.mark()
    raw.standing = flags(model, sensor, *raised)
    seconds = OCCURS_WITHIN * ctx.scale
    found = await watch(probe, asked, seconds, lambda u: bool(_runs(model, u, kinds)))
    if not _runs(model, found, kinds):
        raise Inconclusive(
            f"the robot raised no event or memory event within {seconds:.2g} s of their request,"
            " so its silence before says nothing"
        )


# -- memory events: sent again until acknowledged (R-RSP-28, R-RSP-29) -------------------------


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
