"""rsp/motion: the robot's motion filter between packets (D-RSP-20), as a monitor shows it
(D-RSP-27): values that arrive together count only as the newest (*collapse*, R-RSP-34), and a
value after lost packets is reached over a period, not in one jump (*interpolate*, R-RSP-35). The
harness plays the local system, packet by packet: a DOWNLINK carrying the effector's value after
each UPLINK (D-RSP-18: in every DOWNLINK while it is active). The filter's stop on a lost link is
rsp_pace's.

Each case drives one field of a numeric effector with a monitor to values far apart in the
field's range (or in ±1000 where it has none), so that the monitor's tolerance (`close_to`) tells
them apart whatever body carries them out.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

from rcmlconf.conformance.context import Context
from rcmlconf.conformance.probes.rsp_datagram import Datagram, newer, sequence_of
from rcmlconf.conformance.probes.rsp_devices import (
    close_to,
    flags,
    monitored,
    value_item,
    values_of,
    visible,
)
from rcmlconf.conformance.probes.rsp_exchanges import raw_session
from rcmlconf.conformance.probes.rsp_probe import RspProbe
from rcmlconf.conformance.probes.rsp_raw import RawSession
from rcmlconf.conformance.registry import case
from rcmlconf.conformance.roles import Role
from rcmlconf.conformance.verdicts import Inconclusive
from rcmlconf.rsp.codec import Item, PacketType
from rcmlconf.rsp.model import Device, Field
from rcmlconf.values import Kind, Value

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
