"""rsp/motion: the robot's motion filter between packets (D-RSP-20), as a monitor shows it
(D-RSP-27). The harness plays the local system.

- Values that arrive together count only as the newest (*collapse*, R-RSP-34).
- A value after lost packets is reached over a period, not in one jump (*interpolate*,
  R-RSP-35).
- On a lost link, an onLoss=zero effector stops 25 periods into the silence, and the others
  hold (R-RSP-34, R-RSP-36).

The harness sends packet by packet: a DOWNLINK with the effector's value after each UPLINK
(D-RSP-18: in every DOWNLINK while it is active). Each case drives one field of a numeric
effector with a monitor to values far apart in the field's range (or in ±1000 where it has
none). So the monitor's tolerance (`close_to`) tells them apart, whatever body carries them out.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

from rcmlconf.conformance.context import Context
from rcmlconf.conformance.probes.held import margin, seen_by
from rcmlconf.conformance.probes.pace import ms
from rcmlconf.conformance.probes.rsp_datagram import SESSION_AT, Datagram, newer, sequence_of
from rcmlconf.conformance.probes.rsp_devices import (
    close_to,
    flags,
    monitored,
    value_item,
    values_of,
    visible,
)
from rcmlconf.conformance.probes.rsp_driven import Driven, drive
from rcmlconf.conformance.probes.rsp_exchanges import raw_session
from rcmlconf.conformance.probes.rsp_probe import RspProbe
from rcmlconf.conformance.probes.rsp_raw import RawSession
from rcmlconf.conformance.registry import case
from rcmlconf.conformance.roles import Role
from rcmlconf.conformance.rsp_numbers import (
    LOST_PERIODS,
    STOP_LAG,
)
from rcmlconf.conformance.verdicts import Inconclusive
from rcmlconf.rsp.codec import Item, PacketType
from rcmlconf.rsp.model import Device, Field, OnLoss
from rcmlconf.values import Kind, Value
from rcmlconf.values.shown import values_text

#: The field's range where it gives none (as `visible`'s).
UNBOUNDED = 1000.0
#: Distinct values that far apart at least (in the field's units) tell a queue's steps apart.
NARROWEST = 100.0
#: rsp/motion/collapse: the earlier values of its burst, and the UPLINKs it watches after it.
QUEUED = 9
WATCHED = 12
#: D-RSP-27: UPLINKs that may show one earlier value of a burst.
FOLLOWED = 3
#: rsp/motion/interpolate: periods of silence before a value (D-RSP-27), and tries.
SILENT = 3
TRIES = 3
#: D-RSP-27: the UPLINK, from the first that took a value after a silence, that reports it.
REACHED_BY = 3
#: UPLINKs a value may take to show before the case gives up on it.
SETTLING = 40


@dataclass
class _Driven:
    """A session by hand requesting an effector's monitor, its module active; one field driven,
    the others held at a `visible` value."""

    probe: RspProbe
    raw: RawSession
    effector: Device
    monitor: Device
    low: float
    high: float
    others: dict[str, Value] = field(default_factory=dict)

    @property
    def field(self) -> Field:
        return self.effector.fields[0]

    def at(self, share: float) -> int | float:
        """The driven field's value `share` of the way up its range."""
        value = self.low + (self.high - self.low) * share
        return round(value) if self.field.type.base.kind is Kind.INTEGER else value

    def item(self, value: float) -> Item:
        return value_item(self.effector, {self.field.name: value, **self.others})

    def reading(self, uplink: Datagram) -> float | None:
        """The driven field as the monitor reports it in `uplink`; None if it does not."""
        values = values_of(uplink, self.monitor)
        found = None if values is None else values.get(self.field.name)
        return float(found) if isinstance(found, int | float) else None

    def near(self, reading: float, value: float) -> bool:
        return close_to(self.field, reading, value)

    def readings(self, sequence: int) -> list[float]:
        """What the monitor reported in the UPLINKs sent after the robot took DOWNLINK
        `sequence` (R-RSP-15), in order."""
        found = [
            self.reading(d)
            for d in self.probe.packets(PacketType.UPLINK)
            if newer(d.header.last_received, sequence)
        ]
        return [r for r in found if r is not None]

    async def beat(self, value: float, *, until: Callable[[], bool], uplinks: int) -> None:
        """After each UPLINK a DOWNLINK carrying `value`, until `until` holds or `uplinks`
        UPLINKs came. Only after one: a DOWNLINK right after the one that brought a value would
        end its ramp (D-RSP-20 takes a value that comes on time whole)."""
        for _ in range(uplinks):
            if until():
                return
            await self.uplink()
            self.raw.downlink([self.item(value)])

    async def uplink(self) -> None:
        """The robot's next UPLINK; Inconclusive if none comes within two periods."""
        probe, period = self.probe, self.raw.period
        if await probe.next(PacketType.UPLINK, wait=2 * period + probe.quiet) is None:
            raise Inconclusive(f"no UPLINK within two periods ({2 * period * 1000:g} ms)")

    async def settle(self, value: float) -> None:
        """The monitor reporting `value` twice running; Inconclusive if it never does."""
        sequence = sequence_of(self.raw.downlink([self.item(value)]))

        def settled() -> bool:
            last = self.readings(sequence)[-2:]
            return len(last) == 2 and all(self.near(r, value) for r in last)

        await self.beat(value, until=settled, uplinks=SETTLING)
        if not settled():
            raise Inconclusive(f"{self.monitor.name} never reported {value}")


async def _driven(ctx: Context) -> _Driven:
    """A session driving a numeric effector with a monitor whose first field is one number with
    room for values far apart (NotApplicable when the model has none)."""
    probe, raw = await raw_session(ctx)
    model = probe.model

    def roomy(effector: Device) -> bool:
        first = effector.fields[0]
        low, high = _range(first)
        return not first.type.is_array and high - low >= NARROWEST

    effector, monitor = monitored(model, roomy)
    raw.standing = flags(model, effector, monitor)
    low, high = _range(effector.fields[0])
    others = {f.name: visible(f) for f in effector.fields[1:]}
    return _Driven(probe, raw, effector, monitor, low, high, others)


def _range(found: Field) -> tuple[float, float]:
    low = found.minimum if found.minimum is not None else -UNBOUNDED
    high = found.maximum if found.maximum is not None else UNBOUNDED
    return float(low), float(high)


@case(
    "rsp/motion/collapse",
    f"Values of an effector sent back to back count only as the newest: its monitor does not"
    f" follow the {QUEUED} before it",
    ["R-RSP-34"],
    role=Role.ROBOT,
)
async def collapse(ctx: Context) -> None:
    driven = await _driven(ctx)
    raw, monitor = driven.raw, driven.monitor
    before, newest = driven.at(0.5), driven.at(0.7)
    # Off the way from `before` to `newest`, all on the far side, each its own (D-RSP-27).
    earlier = [driven.at(0.05 + 0.025 * k) for k in range(QUEUED)]
    await driven.settle(before)
    burst = raw.next_sequence
    for value in [*earlier, newest]:
        raw.downlink([driven.item(value)])
    await driven.beat(
        newest, until=lambda: len(driven.readings(burst)) >= WATCHED, uplinks=WATCHED + 2
    )
    seen = driven.readings(burst)[:WATCHED]
    off = [r for r in seen if r < before and not driven.near(r, before)]
    ctx.expect(
        len(off) <= FOLLOWED,
        f"{monitor.name} going from {before} to {newest}, the newest of {QUEUED + 1} values sent"
        f" back to back: on the side of the {QUEUED} before it ({earlier[-1]} and below) in"
        f" {FOLLOWED} UPLINKs at most (D-RSP-27: one control period may take one of them)",
        f"in {len(off)} of {len(seen)}: " + ", ".join(f"{r:g}" for r in seen),
    )
    if not any(r > before and not driven.near(r, before) for r in seen):
        # A robot that took none of the values follows no earlier one either.
        raise Inconclusive(
            f"{monitor.name} never moved toward {newest} in {len(seen)} UPLINKs after the burst"
        )


@case(
    "rsp/motion/interpolate",
    f"A value after {SILENT} periods of silence (as after lost packets) is reached over a period,"
    " not in one jump",
    ["R-RSP-35"],
    role=Role.ROBOT,
)
async def interpolate(ctx: Context) -> None:
    driven = await _driven(ctx)
    values = driven.at(0.3), driven.at(0.7)
    await driven.settle(values[0])
    # Without a silence the filter takes a value whole (D-RSP-20): what shows between then is the
    # body's own (D-RSP-27).
    if _between(driven, values[0], values[1], await _step(driven, values[0], values[1], 0)):
        ctx.cannot_check(
            f"that the filter ramps: {driven.monitor.name} shows a value sent without a silence"
            " gradually too (the body moves gradually by itself)"
        )
        return
    tries = []
    for k in range(TRIES):
        start, end = values[(k + 1) % 2], values[k % 2]
        seen = await _step(driven, start, end, SILENT)
        tries.append(seen)
        if _between(driven, start, end, seen):
            ctx.expect(  # the ramp's one period, read in UPLINKs (a held harness stretches it)
                any(driven.near(r, end) for r in seen[:REACHED_BY]),
                f"{driven.monitor.name} at {end} by the {REACHED_BY}rd UPLINK that took it"
                " (D-RSP-27: over one period)",
                ", ".join(f"{r:g}" for r in seen),
                timing=True,
            )
            return
    ctx.expect(  # the sends' phase is read off the harness's clock: a timing check
        False,
        f"{driven.monitor.name} between the value in force and one sent after {SILENT} silent"
        f" periods, in one of {TRIES} tries (D-RSP-27: over one period, not in one jump)",
        "; ".join(", ".join(f"{r:g}" for r in seen) for seen in tries),
        timing=True,
    )


def _between(driven: _Driven, start: float, end: float, seen: list[float]) -> bool:
    """Whether a reading in `seen` lies strictly between `start` and `end`, near neither."""
    low, high = sorted((start, end))
    return any(
        low < r < high and not driven.near(r, start) and not driven.near(r, end) for r in seen
    )


async def _step(driven: _Driven, start: float, end: float, silent: int) -> list[float]:
    """`end` sent half a period after an UPLINK, after `silent` periods without a DOWNLINK
    (their numbers skipped, as lost) or right on the beat of `start`; what the monitor reported
    from the first UPLINK that took it until it reported `end` (or as many as SETTLING)."""
    probe, raw = driven.probe, driven.raw
    period = raw.period
    if silent:
        raw.skip(silent)
        await probe.listen(silent * period)
    await driven.uplink()
    if not silent:
        raw.downlink([driven.item(start)])
    await probe.listen(period / 2)
    sequence = sequence_of(raw.downlink([driven.item(end)]))

    def reached() -> bool:
        return any(driven.near(r, end) for r in driven.readings(sequence))

    await driven.beat(end, until=reached, uplinks=SETTLING)
    seen = driven.readings(sequence)
    done = next((k for k, r in enumerate(seen) if driven.near(r, end)), len(seen) - 1)
    return seen[: done + 1]


# -- a lost link: stop or hold (D-RSP-20; R-RSP-34, R-RSP-36) ----------------------------------


#: D-RSP-20: a stop is seen at most this many periods after the link is lost (the control period
#: to come round, then the UPLINK).
STOP_PERIODS = 2


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
