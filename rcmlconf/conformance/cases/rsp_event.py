"""rsp/event, rsp/audio: what the robot raises and plays. Events ride the three UPLINKs after
they occur (D-RSP-17, R-RSP-30); occurrences are numbered 0, 1, 2, ... per device and repeated
with their ID (D-RSP-5, R-RSP-24); nothing is reported of a device not requested (D-RSP-14,
R-RSP-23). The audio processor plays a speaker's fragments in order and drops a late one
(D-RSP-22, R-RSP-39), which a monitor of the speaker shows (D-RSP-23, R-RSP-40): a model without
such a monitor (CUBO's) leaves the rsp/audio cases not applicable. The harness plays the local
system; how it waits for what the robot raises is `probes.rsp_raised`'s, and memory events are
rsp_memory_events'.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from rcmlconf.conformance.context import Context
from rcmlconf.conformance.probes.rsp_datagram import Datagram, sequence_of
from rcmlconf.conformance.probes.rsp_devices import (
    flags,
    of_kind,
    reported,
    value_item,
    values_of,
    zero_values,
)
from rcmlconf.conformance.probes.rsp_exchanges import fresh_uplink, taken
from rcmlconf.conformance.probes.rsp_probe import RspProbe
from rcmlconf.conformance.probes.rsp_raised import (
    OCCURS_WITHIN,
    id_space,
    missing,
    nothing_raised,
    received_uplinks,
    requesting,
    watch,
)
from rcmlconf.conformance.probes.rsp_raw import RawSession
from rcmlconf.conformance.registry import case
from rcmlconf.conformance.roles import Role
from rcmlconf.conformance.verdicts import Inconclusive, NotApplicable
from rcmlconf.rsp.codec import PacketType
from rcmlconf.rsp.model import Device, DeviceKind, RobotModel
from rcmlconf.values import Kind, Value

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


# -- audio: what the speaker played (D-RSP-22, D-RSP-23) ---------------------------------------


def _audio(model: RobotModel | None) -> tuple[Device, Device]:
    """An audio effector (a uint16 fragment number and bytes of samples, D-RSP-22) and a monitor
    of it (D-RSP-23); NotApplicable when the model has none."""
    if model is None:
        raise NotApplicable("the RSP robot's model is not known (give --rsp-model)")
    for monitor in of_kind(model, DeviceKind.MONITOR):
        effector = model.device(monitor.of or "")
        if effector is None or len(effector.fields) != 2:
            continue
        number, samples = effector.fields
        if (
            number.type.base.name == "uint16"
            and not number.type.is_array
            and samples.type.base.kind is Kind.BYTES
            and not samples.type.is_array
        ):
            return effector, monitor
    raise NotApplicable(
        f"{model.name} has no monitor of an audio effector (D-RSP-23): what its audio processor"
        " plays cannot be seen"
    )


def _fragment(effector: Device, number: int) -> dict[str, Value]:
    number_field, samples_field = effector.fields
    text = f"fragment {number}".encode()
    samples = text[: samples_field.type.size] if samples_field.type.size else text
    return {number_field.name: number % 65536, samples_field.name: samples}


async def _play(
    ctx: Context,
    probe: RspProbe,
    raw: RawSession,
    effector: Device,
    monitor: Device,
    number: int,
    wanted: int,
    requirement: str,
    why: str,
) -> None:
    """Send fragment `number` in a new DOWNLINK; the monitor must then report fragment
    `wanted` (R-RSP-40), in the first UPLINK sent after the robot received it and the few after."""
    sent = raw.downlink([value_item(effector, _fragment(effector, number))])
    expected = _fragment(effector, wanted)
    first = await fresh_uplink(probe, sequence_of(sent))
    if first is None:
        raise Inconclusive(f"no UPLINK after fragment {number}")
    await probe.listen(3 * raw.period)
    reports = [
        values_of(u, monitor)
        for u in probe.packets(PacketType.UPLINK, after=probe.received.index(first))
    ]
    wrong = [dict(r) for r in reports if r is not None and dict(r) != expected]
    ctx.expect(
        not wrong and any(r is not None for r in reports),
        f"{monitor.name} reporting fragment {wanted} ({why})",
        "none" if not wrong else str(wrong[0]),
        requirement,
    )


async def _listening(ctx: Context) -> tuple[RspProbe, RawSession, Device, Device]:
    """A session requesting the audio effector's monitor, which reports zero values before any
    fragment is played (D-RSP-23)."""
    effector, monitor = _audio(ctx.target.rsp_model)
    probe, raw = await requesting(ctx, monitor, effector)
    first = await taken(probe, raw)
    if first is None:
        raise Inconclusive(f"no UPLINK reporting {monitor.name}")
    before = values_of(first, monitor)
    zero = zero_values(effector)
    ctx.expect(
        before is not None and dict(before) == zero,
        f"{monitor.name} at {zero} before any fragment is played",
        str(dict(before)) if before is not None else "not reported",
        "R-RSP-40",
    )
    return probe, raw, effector, monitor


@case(
    "rsp/audio/in-order",
    "A speaker's monitor reports each fragment as it is played in order, and one after a gap",
    ["R-RSP-39", "R-RSP-40"],
    role=Role.ROBOT,
)
async def audio_in_order(ctx: Context) -> None:
    probe, raw, effector, monitor = await _listening(ctx)
    for number in range(3):
        await _play(ctx, probe, raw, effector, monitor, number, number, "R-RSP-40", "played")
    await _play(ctx, probe, raw, effector, monitor, 5, 5, "R-RSP-39", "played after a gap of 2")


@case(
    "rsp/audio/late-dropped",
    "A fragment older than the one played last is dropped: the speaker's monitor does not go back",
    ["R-RSP-39", "R-RSP-40"],
    role=Role.ROBOT,
)
async def audio_late_dropped(ctx: Context) -> None:
    probe, raw, effector, monitor = await _listening(ctx)
    await _play(ctx, probe, raw, effector, monitor, 10, 10, "R-RSP-40", "played")
    await _play(ctx, probe, raw, effector, monitor, 12, 12, "R-RSP-39", "played after a gap")
    await _play(ctx, probe, raw, effector, monitor, 11, 12, "R-RSP-39", "11 came late: dropped")
    await _play(ctx, probe, raw, effector, monitor, 13, 13, "R-RSP-39", "played after it")
