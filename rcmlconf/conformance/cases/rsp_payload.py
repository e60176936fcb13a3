"""rsp/payload: the payloads of the robot's packets and of the local system's (D-RSP-14).

What the robot does with them, well-formed or not, newer or late (D-RSP-15; R-RSP-16,
R-RSP-19, R-RSP-23, R-RSP-26, R-RSP-34). A late DOWNLINK's states are not applied over a newer
packet's: its effector values, its request and module bits, and its buffer byte (R-RSP-19).
The harness plays the local system.
"""

from __future__ import annotations

from rcmlconf.conformance.context import Context
from rcmlconf.conformance.probes.awaited import came
from rcmlconf.conformance.probes.rsp_buffer import FROM_ROBOT, durable, keyframe, take
from rcmlconf.conformance.probes.rsp_datagram import Datagram, sequence_of
from rcmlconf.conformance.probes.rsp_devices import (
    close_to,
    first,
    flags,
    monitored,
    of_kind,
    reported,
    value_item,
    values_of,
    visible,
)
from rcmlconf.conformance.probes.rsp_driven import drive
from rcmlconf.conformance.probes.rsp_exchanges import (
    dropped_then_taken,
    fresh,
    late_acked,
    must_take,
    raw_session,
    requested_uplinks,
    taken,
    uplinks_within,
)
from rcmlconf.conformance.registry import case
from rcmlconf.conformance.roles import Role
from rcmlconf.conformance.rsp_numbers import START_PERIODS
from rcmlconf.conformance.verdicts import Failed, Inconclusive, NotApplicable
from rcmlconf.rsp.codec import CLEAR_BUFFER, PacketType
from rcmlconf.rsp.model import DeviceKind


@case(
    "rsp/payload/trailing-byte",
    "A DOWNLINK with a byte after its last payload is dropped unanswered",
    ["R-RSP-16", "R-RSP-18"],
    role=Role.ROBOT,
)
async def trailing_byte(ctx: Context) -> None:
    probe, raw = await raw_session(ctx)
    await dropped_then_taken(ctx, probe, raw, lambda d: d + b"\x00", "R-RSP-16", "a trailing byte")


@case(
    "rsp/payload/cut-short",
    "A DOWNLINK whose last payload is a byte short is dropped unanswered",
    ["R-RSP-16", "R-RSP-18"],
    role=Role.ROBOT,
)
async def cut_short(ctx: Context) -> None:
    probe, raw = await raw_session(ctx)
    await dropped_then_taken(ctx, probe, raw, lambda d: d[:-1], "R-RSP-16", "a payload cut short")


@case(
    "rsp/payload/every-state",
    "With every sensor and monitor requested, each UPLINK reports all of them, laid out by field",
    ["R-RSP-23", "R-RSP-16"],
    role=Role.ROBOT,
)
async def every_state(ctx: Context) -> None:
    probe, raw = await raw_session(ctx)
    model = probe.model
    states = of_kind(model, DeviceKind.SENSOR, DeviceKind.MONITOR)
    if not states:
        raise NotApplicable("no sensor or monitor")
    uplinks = await requested_uplinks(probe, raw, states, 4)
    names = {d.name for d in states}
    for found in uplinks:
        ctx.expect(
            found.devices(model) == names,
            f"all {len(names)} sensors and monitors",
            f"{sorted(found.devices(model) ^ names)} missing or extra",
            "R-RSP-23",
        )


@case(
    "rsp/payload/effector-applied",
    "An effector value in DOWNLINKs is applied: its monitor reports it",
    ["R-RSP-34"],
    role=Role.ROBOT,
)
async def effector_applied(ctx: Context) -> None:
    driven = await drive(ctx)
    await driven.shown(ctx, "R-RSP-34")


@case(
    "rsp/payload/effector-held",
    "An effector keeps its value when the DOWNLINKs stop carrying it (hold, D-RSP-20)",
    ["R-RSP-34"],
    role=Role.ROBOT,
)
async def effector_held(ctx: Context) -> None:
    driven = await drive(ctx)
    probe = driven.probe
    await driven.settled()
    probe.session.set_active(driven.effector.name, False)
    since = probe.now + 2 * probe.session.period
    await probe.listen(12 * probe.session.period)
    moved = await driven.moved(since)
    ctx.expect(moved is None, f"{driven.monitor.name} holding {driven.wanted}", str(moved))


@case(
    "rsp/payload/late-state-ignored",
    "An effector value in a late DOWNLINK (not newer) is not applied over the newer one",
    ["R-RSP-19"],
    role=Role.ROBOT,
)
async def late_state_ignored(ctx: Context) -> None:
    probe, raw = await raw_session(ctx)
    model = probe.model
    effector, monitor = monitored(model)
    field = effector.fields[0]
    newest = {f.name: visible(f) for f in effector.fields}
    older = {f.name: f.zero() for f in effector.fields}
    request = flags(model, effector, monitor)
    raw.skip(5)
    await taken(probe, raw, [*request, value_item(effector, newest)], wait=probe.quiet)
    top = sequence_of(raw.last)
    raw.rewind(top - 3)
    raw.downlink([*request, value_item(effector, older)])
    raw.rewind(top + 1)

    def reports(found: Datagram) -> bool:
        values = values_of(found, monitor)
        return values is not None and close_to(field, values.get(field.name), newest[field.name])

    def last() -> str:
        found = (values_of(d, monitor) for d in reversed(probe.received) if values_of(d, monitor))
        return f"{monitor.name} at {next(found, None)}"

    # An UPLINK since the robot took the newer packet: before the late one, or after.
    await came(
        ctx,
        probe,
        PacketType.UPLINK,
        f"{monitor.name} reaching {newest} (the newer packet's)",
        after=0,
        where=fresh(lambda: top, reports),
        wait=min(probe.wait, 0.45),
        instead=last,
    )
    raw.downlink(request)  # the link kept alive
    for later in await uplinks_within(probe, 4, raw.period, "the late DOWNLINK"):
        if not reports(later):
            ctx.expect(False, f"{monitor.name} staying at {newest}", str(values_of(later, monitor)))


@case(
    "rsp/payload/late-occurrence-taken",
    "A command in a late DOWNLINK (not newer, never seen) is taken and acknowledged",
    ["R-RSP-26"],
    role=Role.ROBOT,
)
async def late_occurrence_taken(ctx: Context) -> None:
    probe, raw = await raw_session(ctx)
    command = first(probe.model, DeviceKind.COMMAND)
    raw.skip(5)
    top = sequence_of(raw.downlink())
    expected = f"ACK of {command.name} #0 in DOWNLINK #{top - 2}, after #{top}"
    await late_acked(ctx, probe, raw, command, 0, top - 2, resume=top + 1, expected=expected)


@case(
    "rsp/payload/inactive-module",
    "An effector value sent while its module is inactive is not applied",
    ["R-RSP-23"],
    role=Role.ROBOT,
)
async def inactive_module(ctx: Context) -> None:
    model = ctx.target.rsp_model
    if model is None:
        raise NotApplicable("no RSP model")
    effector, monitor = monitored(model, lambda e: e.module is not None)
    probe, raw = await raw_session(ctx)
    field = effector.fields[0]
    wanted = {f.name: visible(f) for f in effector.fields}
    monitor_only = flags(model, monitor)
    gated = [i for i in monitor_only if model.devices[i.device].name != effector.module]
    for _ in range(3):
        raw.downlink([*gated, value_item(effector, wanted)])
        await probe.listen(raw.period)
    await must_take(
        ctx,
        probe,
        raw,
        monitor_only,
        f"{monitor.name} reported once {effector.module} is active",
        wait=max(0.3, 10 * raw.period),
    )
    later = await uplinks_within(probe, 4, raw.period, f"{monitor.name} was reported")
    target = wanted[field.name]
    assert isinstance(target, int | float)
    for found in later[-3:]:
        values = values_of(found, monitor)
        actual = values.get(field.name) if values is not None else None
        ctx.expect(
            isinstance(actual, int | float) and abs(actual) < abs(target) / 2,
            f"{monitor.name} near its zero (the value of an inactive module not applied)",
            str(values),
        )


# -- the other states of a late DOWNLINK (D-RSP-15, R-RSP-19) ----------------------------------


#: Periods late-request-ignored and late-clear-buffer-ignored watch the UPLINKs after the late
#: DOWNLINK: one for the robot to take it, the rest to report what it then holds (an UPLINK
#: every T while a sensor is requested).
WATCH = 4


@case(
    "rsp/payload/late-request-ignored",
    "A late DOWNLINK (not newer) requesting another sensor does not change what the UPLINKs report",
    ["R-RSP-19"],
    role=Role.ROBOT,
)
async def late_request_ignored(ctx: Context) -> None:
    probe, raw = await raw_session(ctx)
    model = probe.model
    asked, other = reported(model, 2)
    raw.skip(5)  # numbers left unused: the late packet's is one never seen (D-RSP-15)
    if await taken(probe, raw, flags(model, asked)) is None:
        raise Inconclusive(f"no UPLINK after the DOWNLINK requesting {asked.name}")
    top = sequence_of(raw.last)
    raw.rewind(top - 3)
    late = raw.downlink(flags(model, other))
    raw.rewind(top + 1)
    uplinks = await uplinks_within(probe, WATCH, raw.period, "the late DOWNLINK")
    wrong = [d for d in uplinks if d.devices(model) != {asked.name}]
    ctx.expect(
        not wrong,
        f"UPLINKs reporting {asked.name} only, as DOWNLINK #{top} (the newest) requests, not"
        f" {other.name} as the late #{sequence_of(late)} does",
        f"{sorted(wrong[0].devices(model))} in UPLINK #{wrong[0].header.sequence}" if wrong else "",
    )


#: Memory commands late-clear-buffer-ignored leaves waiting behind the one executing: a Clear
#: Buffer frees them all at once, more than one command done in the meantime could.
WAITING = 2


@case(
    "rsp/payload/late-clear-buffer-ignored",
    "A late DOWNLINK (not newer) with Clear Buffer leaves the memory commands waiting in the"
    " buffer",
    ["R-RSP-19"],
    role=Role.ROBOT,
)
async def late_clear_buffer_ignored(ctx: Context) -> None:
    probe, raw = await raw_session(ctx)
    model = probe.model
    memory = first(model, DeviceKind.MEMORY_COMMAND)
    raw.standing = flags(model, reported(model, 1)[0])  # an UPLINK every T
    await take(ctx, probe, raw, memory, 0)
    await probe.listen(START_PERIODS * raw.period)  # #0 has left the buffer (R-RSP-31)
    ident = 1
    while ident <= WAITING and probe.received[-1].header.buffer > 0:
        await take(ctx, probe, raw, memory, ident)
        ident += 1
    raw.skip(5)  # numbers left unused: the late packet's is one never seen (D-RSP-15)
    before = await taken(probe, raw)
    if before is None:
        raise Inconclusive("no UPLINK after the memory commands")
    held, top = before.header.buffer, sequence_of(raw.last)
    # The late packet repeats the newest memory command: an old ID, acknowledged again and not
    # taken (D-RSP-16), whose ACK says the robot read the packet (D-RSP-15: a late packet's
    # occurrences are handled) and gives its free buffers then.
    repeated = ident - 1
    mark = probe.mark()
    ack = await late_acked(
        ctx,
        probe,
        raw,
        memory,
        repeated,
        top - 3,
        resume=top + 1,
        expected=f"ACK of {memory.name} #{repeated} in a late DOWNLINK with Clear Buffer",
        values=keyframe(memory),
        buffer=CLEAR_BUFFER,
    )
    await probe.listen(WATCH * raw.period)
    counts = [d.header.buffer for d in probe.packets(FROM_ROBOT, after=mark)]
    cleared = await taken(probe, raw, buffer=CLEAR_BUFFER)
    if cleared is None:
        raise Inconclusive("no UPLINK after a newer DOWNLINK with Clear Buffer")
    empty = cleared.header.buffer
    if empty <= held:
        raise Inconclusive(
            f"{held} free, {empty} after a newer Clear Buffer: nothing waited in the buffer (or"
            " its Clear Buffer frees nothing, rsp/reliable/clear-buffer's to judge)"
        )
    if all(count < empty for count in counts):
        return
    expected = (
        f"{held} free after late DOWNLINK #{top - 3} with Clear Buffer (not newer than #{top}: its"
        " buffer byte not applied, D-RSP-15)"
    )
    got = f"{counts} free, {empty} as a newer Clear Buffer leaves"
    # Commands done in the meantime free one buffer each: all of them at the late packet's ACK,
    # or any keyframe of CUBO's (D-RSP-19: they take their 30 s), is its Clear Buffer.
    if durable(probe, memory) or (ack.header.buffer >= empty and empty - held >= WAITING):
        raise Failed("R-RSP-19", expected, got)
    raise Inconclusive(f"the robot executes memory commands fast: expected {expected}; got {got}")
