"""rsp/event, rsp/audio: what the robot raises and plays. Events ride the three UPLINKs after
they occur (D-RSP-17, R-RSP-30); occurrences are numbered 0, 1, 2, ... per device and repeated
with their ID (D-RSP-5, R-RSP-24); a memory event is sent again after each retransmission timeout
until acknowledged, not sooner (R-RSP-28), and the next one of its device waits for that
acknowledgement (R-RSP-29); nothing is reported of a device not requested (D-RSP-14, R-RSP-23).
The audio processor plays a speaker's fragments in order and drops a late one (D-RSP-22,
R-RSP-39), which a monitor of the speaker shows (D-RSP-23, R-RSP-40): a model without such a
monitor (CUBO's) leaves the rsp/audio cases not applicable. The harness plays the local system.

A robot raises events when something happens to it, and a case cannot make anything happen: it
requests the robot's events and memory events and waits, a bounded time, for what the robot
raises on its own (the reference CUBO's simulated person presses its buttons about once a second
and its battery dips about as often). A robot that raises nothing in that time leaves the case
inconclusive, never passed. While it waits, the case keeps the session alive with a DOWNLINK of
its requests every few periods (`_Beat`), and acknowledges a memory event only when it says
(`_ack`), so that it can watch the robot send it again.
"""

from __future__ import annotations

import asyncio
import contextlib
import itertools
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from rcmlconf.conformance.context import Context
from rcmlconf.conformance.probes.rsp import (
    Datagram,
    RawSession,
    RspProbe,
    flags,
    fresh_uplink,
    newer,
    of_kind,
    raw_session,
    reported,
    sequence_of,
    summary,
    taken,
    value_item,
    values_of,
    zero_values,
)
from rcmlconf.conformance.registry import Role, case
from rcmlconf.conformance.rsp_numbers import STAMP_ROUNDING, resent_within, unmeasured_rto
from rcmlconf.conformance.verdicts import Inconclusive, NotApplicable
from rcmlconf.rsp.codec import Item, MapBody, PacketType
from rcmlconf.rsp.model import Device, DeviceKind, RobotModel
from rcmlconf.values import Kind, Value

#: D-RSP-25: how long a case watches for the robot to raise what it needs, seconds (before
#: --timeout-scale).
OCCURS_WITHIN = 2.0
#: D-RSP-17: an event rides this many UPLINKs.
RIDES = 3
#: Retransmissions a case times: the first at 10 T, the second at 20 T.
RESENDS = 2
#: How long the memory-event case withholds its ACK to leave the robot a second occurrence to hold
#: back (R-RSP-29), seconds.
HOLD = 1.3
#: D-RSP-13: periods between two packets of a side with nothing new to send.
KEEPALIVE = 5
#: ACK packets sent for one acknowledgement: the robot must have lost them all to send the
#: occurrence again once it has a later packet (a false failure under 20 % loss: 1 in 125).
ACK_COPIES = 3
_SEQUENCE = 1 << 16
_HALF = _SEQUENCE // 2


# -- a local system that beats and acknowledges when told ---------------------------------------


class _Beat:
    """A DOWNLINK with the session's standing requests (R-RSP-23) every `KEEPALIVE` periods until
    the case ends. D-RSP-13 would have one every period; this is as often as it asks of a side
    with nothing to say: requests stand until the next DOWNLINK (D-RSP-14), the robot never finds
    the link lost, and its own packets stay readable in the transcript."""

    def __init__(self, ctx: Context, raw: RawSession) -> None:
        self.raw = raw
        self._task = asyncio.get_running_loop().create_task(self._run())
        ctx.on_close(self.stop)

    def stop(self) -> None:
        self._task.cancel()

    async def _run(self) -> None:
        raw = self.raw
        seen = 0
        with contextlib.suppress(asyncio.CancelledError):
            while not raw.ended and not raw.probe.closed:
                # R-RSP-15: the newest sequence number received from the robot in the session.
                for found in raw.probe.received[seen:]:
                    if raw.session_id and found.header.session_id == raw.session_id:
                        raw.wire.tracker.see(found.header.sequence)
                seen = len(raw.probe.received)
                raw.downlink()
                await asyncio.sleep(KEEPALIVE * raw.period)


async def _requesting(ctx: Context, *devices: Device) -> tuple[RspProbe, RawSession]:
    """A session by hand whose DOWNLINKs request `devices`."""
    probe, raw = await raw_session(ctx)
    raw.standing = flags(probe.model, *devices)
    _Beat(ctx, raw)
    return probe, raw


def _ack(raw: RawSession, found: Device, ident: int) -> tuple[int, int]:
    """ACK occurrence `ident` of memory event `found`, in ACK_COPIES packets so that a lost one
    does not lose it (an ACK of what is already acknowledged is nothing to its receiver); the
    sequence numbers of the first and the last."""
    sent = [
        sequence_of(raw.send(PacketType.ACK, MapBody((Item(found.position, ident),))))
        for _ in range(ACK_COPIES)
    ]
    return sent[0], sent[-1]


def _ids(model: RobotModel) -> int:
    return 1 << (8 * model.id_length)


def _uplinks(probe: RspProbe, after: int) -> list[Datagram]:
    """The UPLINKs received from `after`, each once (a duplicate dropped), in the robot's order
    (by sequence number: a reordered one in its place)."""
    unique: dict[int, Datagram] = {}
    for found in probe.packets(PacketType.UPLINK, after=after):
        unique.setdefault(found.header.sequence, found)
    if not unique:
        return []
    first = next(iter(unique))
    return sorted(unique.values(), key=lambda d: (d.header.sequence - first + _HALF) % _SEQUENCE)


def _missing(probe: RspProbe, low: Datagram, high: Datagram) -> bool:
    """Whether a packet the robot numbered between `low` and `high` never arrived: lost, and
    what it carried unknown (so what seems missing from the UPLINKs may have been there)."""
    session = low.header.session_id
    got = {d.header.sequence for d in probe.received if d.header.session_id == session}
    span = (high.header.sequence - low.header.sequence) % _SEQUENCE
    return any((low.header.sequence + k) % _SEQUENCE not in got for k in range(1, span))


async def _watch(
    probe: RspProbe, after: int, seconds: float, done: Callable[[list[Datagram]], bool]
) -> list[Datagram]:
    """The UPLINKs received from `after`, once `done` holds of them or `seconds` have passed."""
    deadline = probe.now + seconds
    while True:
        found = _uplinks(probe, after)
        remaining = deadline - probe.now
        if done(found) or remaining <= 0:
            return found
        await probe.next(after=probe.mark(), wait=remaining)


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
        and not _missing(probe, uplinks[first - 1], uplinks[last + 1])
    )


def _events(model: RobotModel) -> list[Device]:
    found = of_kind(model, DeviceKind.EVENT)
    if not found:
        raise NotApplicable(f"{model.name} has no event")
    return found


def _nothing_raised(what: str, seconds: float) -> Inconclusive:
    return Inconclusive(f"the robot raised no {what} within {seconds:.2g} s")


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
    probe, raw = await _requesting(ctx, *events)
    start = probe.mark()
    kinds = {DeviceKind.EVENT}
    seconds = OCCURS_WITHIN * ctx.scale
    uplinks = await _watch(
        probe, start, seconds, lambda u: enough(probe, u, _runs(probe.model, u, kinds))
    )
    runs = _runs(probe.model, uplinks, kinds)
    if not runs:
        raise _nothing_raised("event", seconds)
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
    space = _ids(probe.model)
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
            and not _missing(probe, uplinks[a.uplinks[-1]], uplinks[b.uplinks[0]])
        ]
        ctx.expect(
            (ids[0] == 0 or _missing(probe, welcome, first)) and not skips,
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
    probe, raw = await _requesting(ctx, sensor)  # UPLINKs every period, no occurrence asked for
    start = probe.mark()
    kinds = {DeviceKind.EVENT, DeviceKind.MEMORY_EVENT}
    await probe.listen(OCCURS_WITHIN / 2 * ctx.scale)
    stray = _runs(model, _uplinks(probe, start), kinds)
    ctx.expect(
        not stray,
        "no event or memory event: none requested (D-RSP-14)",
        ", ".join(f"{r.device.name} #{r.id}" for r in stray),
    )
    if not _uplinks(probe, start):
        raise Inconclusive(f"no UPLINK reporting the requested {sensor.name}")
    asked = probe.mark()
    raw.standing = flags(model, sensor, *raised)
    seconds = OCCURS_WITHIN * ctx.scale
    found = await _watch(probe, asked, seconds, lambda u: bool(_runs(model, u, kinds)))
    if not _runs(model, found, kinds):
        raise Inconclusive(
            f"the robot raised no event or memory event within {seconds:.2g} s of their request,"
            " so its silence before says nothing"
        )


# -- memory events: retransmission and one at a time -------------------------------------------


def _memory_event(model: RobotModel | None) -> Device:
    found = of_kind(model, DeviceKind.MEMORY_EVENT) if model is not None else []
    if not found:
        raise NotApplicable(f"{model.name if model else 'the model'} has no memory event")
    return found[0]


def _carrying(uplinks: Sequence[Datagram], found: Device) -> list[tuple[Datagram, int]]:
    """The UPLINKs carrying an occurrence of `found`, with its ID."""
    return [
        (uplink, item.id)
        for uplink in uplinks
        for item in uplink.items
        if item.device == found.position and item.id is not None
    ]


async def _memory_event_raised(
    ctx: Context,
) -> tuple[RspProbe, RawSession, Device, Datagram, int]:
    """A session requesting the model's first memory event device, and the first UPLINK carrying
    an occurrence of it with its ID; Inconclusive if the robot raised none."""
    found = _memory_event(ctx.target.rsp_model)
    probe, raw = await _requesting(ctx, found)
    start = probe.mark()
    seconds = OCCURS_WITHIN * ctx.scale
    uplinks = await _watch(probe, start, seconds, lambda u: bool(_carrying(u, found)))
    carried = _carrying(uplinks, found)
    if not carried:
        raise _nothing_raised(f"{found.name} (memory event)", seconds)
    sent, ident = carried[0]
    return probe, raw, found, sent, ident


def _elapsed_ms(earlier: Datagram, later: Datagram) -> int:
    """Milliseconds of the robot's clock between two of its packets (D-RSP-10's timestamp)."""
    return (later.header.timestamp - earlier.header.timestamp) % (1 << 32)


def _one_at_a_time(ctx: Context, uplinks: Sequence[Datagram], found: Device, ident: int) -> None:
    """R-RSP-29: no other occurrence of `found` while `ident` waits for its ACK."""
    others = [(u, i) for u, i in _carrying(uplinks, found) if i != ident]
    ctx.expect(
        not others,
        f"no other {found.name} before #{ident} is acknowledged",
        ", ".join(f"#{i} in UPLINK #{u.header.sequence}" for u, i in others),
        "R-RSP-29",
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
    probe, raw, memory, sent, ident = await _memory_event_raised(ctx)
    period = raw.period
    begun = probe.received.index(sent)
    sends = [sent]
    for retransmission in range(RESENDS):
        rto = unmeasured_rto(period, retransmission)
        last = sends[-1]
        within = resent_within(rto, period, ctx.scale)  # D-RSP-26
        uplinks = await _watch(
            probe,
            probe.received.index(last) + 1,
            within,
            lambda u: any(i == ident for _, i in _carrying(u, memory)),
        )
        _one_at_a_time(ctx, uplinks, memory, ident)
        again = next((u for u, i in _carrying(uplinks, memory) if i == ident), None)
        if _missing(probe, last, again or probe.received[-1]):
            raise Inconclusive(
                f"packets of the robot's were lost after UPLINK #{last.header.sequence}:"
                f" {memory.name} #{ident} may have been sent again in one of them"
            )
        ctx.expect(  # read off the harness's clock: a timing check
            again is not None,
            f"{memory.name} #{ident} sent again {rto * 1000:.0f} ms after UPLINK"
            f" #{last.header.sequence} (D-RSP-17's timeout, no ACK sent; D-RSP-26: within"
            f" {within * 1000:.0f} ms)",
            f"not within {within * 1000:.0f} ms",
            "R-RSP-28",
            timing=True,
        )
        assert again is not None
        elapsed = _elapsed_ms(last, again)
        ctx.expect(
            elapsed >= rto * 1000 - STAMP_ROUNDING,
            f"{memory.name} #{ident} sent again no sooner than {rto * 1000:.0f} ms"
            f" (retransmission {retransmission + 1}: 10 T, doubled after each)",
            f"{elapsed} ms after (UPLINK #{last.header.sequence} at {last.header.timestamp} ms,"
            f" #{again.header.sequence} at {again.header.timestamp} ms)",
            "R-RSP-28",
        )
        sends.append(again)
    _, acked = _ack(raw, memory, ident)
    acked_at = probe.now
    # As long as the next retransmission could come (D-RSP-26).
    wait = resent_within(unmeasured_rto(period, RESENDS), period, ctx.scale)
    await probe.listen(max(0.0, sends[-1].at + wait - acked_at))
    late = [
        u
        for u, i in _carrying(_uplinks(probe, begun), memory)
        if i == ident and newer(u.header.last_received, acked)
    ]
    ctx.expect(
        not late,
        f"no more {memory.name} #{ident} once the robot has its ACKs (up to #{acked})",
        ", ".join(summary(probe.model, u.header, u.body) for u in late),
        "R-RSP-28",
    )


@case(
    "rsp/event/memory-event-waits",
    "A device's next memory event goes only once the one before is acknowledged, with the next ID",
    ["R-RSP-29", "R-RSP-24"],
    role=Role.ROBOT,
    timeout=7.0,
)
async def memory_event_waits(ctx: Context) -> None:
    probe, raw, memory, sent, ident = await _memory_event_raised(ctx)
    ctx.expect(
        ident == 0, f"{memory.name} #0 first in the session (D-RSP-5)", f"#{ident}", "R-RSP-24"
    )
    begun = probe.received.index(sent)
    await probe.listen(HOLD * ctx.scale)
    _one_at_a_time(ctx, _uplinks(probe, begun), memory, ident)
    acked, _ = _ack(raw, memory, ident)
    after = probe.mark()
    following = (ident + 1) % _ids(probe.model)
    seconds = OCCURS_WITHIN * ctx.scale
    uplinks = await _watch(
        probe, after, seconds, lambda u: any(i != ident for _, i in _carrying(u, memory))
    )
    nxt = next(((u, i) for u, i in _carrying(uplinks, memory) if i != ident), None)
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
    _ack(raw, memory, second)


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
    probe, raw = await _requesting(ctx, monitor, effector)
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
