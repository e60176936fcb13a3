"""rsp/reliable: selective retransmission and the memory-command buffer (D-RSP-16, D-RSP-17,
D-RSP-19; R-RSP-25, R-RSP-26, R-RSP-31, R-RSP-33). The harness plays the local system.

How the buffer cases keep the robot busy is in `probes.rsp_buffer`.
"""

from __future__ import annotations

import statistics
from collections.abc import Awaitable, Callable

from rcmlconf.conformance.context import Context
from rcmlconf.conformance.probes.awaited import came, may_come, must_come
from rcmlconf.conformance.probes.held import margin, seen_by
from rcmlconf.conformance.probes.rsp_buffer import (
    BUSY_MS,
    FROM_ROBOT,
    keyframe,
    not_held,
    take,
)
from rcmlconf.conformance.probes.rsp_datagram import (
    Datagram,
    newer,
    sequence_of,
)
from rcmlconf.conformance.probes.rsp_devices import first, flags, occurrence, reported, zero_values
from rcmlconf.conformance.probes.rsp_exchanges import (
    AT_ONCE,
    acknowledging,
    must_ack,
    raw_session,
    reporting,
    taken,
)
from rcmlconf.conformance.probes.rsp_probe import RspProbe, open_probe
from rcmlconf.conformance.probes.rsp_raw import RawSession, hand_driven
from rcmlconf.conformance.registry import case
from rcmlconf.conformance.roles import Role
from rcmlconf.conformance.rsp_numbers import START_PERIODS
from rcmlconf.conformance.verdicts import Inconclusive, NotApplicable
from rcmlconf.rsp.codec import (
    CLEAR_BUFFER,
    PacketType,
)
from rcmlconf.rsp.model import Device, DeviceKind, RobotModel
from rcmlconf.rsp.session import events

#: rsp/reliable/keyframe-duration's keyframes last this long (ms, scaled): many periods.
KEYFRAME_MS = 400


async def _busy(ctx: Context) -> tuple[RspProbe, RawSession, Device, int]:
    """A session whose robot is busy executing a long memory command; the free buffers then."""
    probe, raw = await raw_session(ctx)
    memory = first(probe.model, DeviceKind.MEMORY_COMMAND)
    raw.standing = flags(probe.model, reported(probe.model, 1)[0])  # an UPLINK every T
    since = probe.now
    taken_at = (await take(ctx, probe, raw, memory, 0)).header.buffer
    # #0 leaves the buffer when the robot starts to execute it, at a control tick of its own
    # (D-RSP-19): wait for an UPLINK that says so, not a fixed time a loaded machine overruns.
    # None may come (#0 may wait behind an earlier session's memory command: nothing says a new
    # session stops it), but one the harness's holds kept it from reading is waited for as much
    # longer as they add up to (D-RSP-26): a count read before #0 left would find the buffer
    # not held once it had.
    start = probe.mark()
    await may_come(
        ctx,
        probe,
        lambda wait: probe.next(
            PacketType.UPLINK, after=start, where=lambda d: d.header.buffer > taken_at, wait=wait
        ),
        since,
        probe.quiet,
        f"UPLINK with more than {taken_at} free buffers ({memory.name} #0 executing)",
    )
    await probe.listen(2 * raw.period)
    return probe, raw, memory, probe.received[-1].header.buffer


def _acks_only(ctx: Context, model: RobotModel, ack: Datagram, found: Device, ident: int) -> None:
    """The ACK names occurrence `ident` of `found` and nothing else (R-RSP-26)."""
    ctx.expect(
        [(i.device, i.id) for i in ack.items] == [(found.position, ident)],
        f"ACK [{found.name}#{ident}]",
        str([(model.devices[i.device].name, i.id) for i in ack.items]),
        "R-RSP-26",
    )


async def _free(probe: RspProbe, raw: RawSession, buffer: int = 0) -> int:
    """The free buffers of the first UPLINK sent after the robot took a DOWNLINK with `buffer`."""
    found = await taken(probe, raw, buffer=buffer)
    if found is None:
        raise Inconclusive("no UPLINK to read the free buffers from")
    return found.header.buffer


# -- acknowledgements ---------------------------------------------------------------------------


@case(
    "rsp/reliable/command-acked",
    "Each command is acknowledged at once by an ACK naming its device and ID, and nothing else",
    ["R-RSP-26", "R-RSP-15"],
    role=Role.ROBOT,
)
async def command_acked(ctx: Context) -> None:
    probe, raw = await raw_session(ctx)
    command = first(probe.model, DeviceKind.COMMAND)
    raw.standing = flags(probe.model, reported(probe.model, 1)[0])  # the beat: an UPLINK every T
    acks = []
    delays = []
    for ident in range(7):
        ack = await take(ctx, probe, raw, command, ident)
        _acks_only(ctx, probe.model, ack, command, ident)
        acks.append(ack)
        sent_at, sent = probe.sent[-1]
        ctx.expect(
            ack.header.last_received == sequence_of(sent),
            f"the ACK saying it received DOWNLINK {sequence_of(sent)}",
            f"last received {ack.header.last_received}",
            "R-RSP-15",
        )
        delays.append(ack.at - sent_at)
        await probe.listen(raw.period * (0.3 + 0.1 * ident))  # each at another phase of T
    if statistics.median(delays) < raw.period / 4:
        return  # at once, plainly
    # A loaded harness delays what it reads: the robot's own clock tells whether it sent each
    # ACK when the DOWNLINK came, or on the beat of its UPLINKs (D-RSP-17: at once).
    beats = [d.header.timestamp for d in probe.packets(PacketType.UPLINK)]
    on_beat = [
        a.header.timestamp
        for a in acks
        if any(abs(a.header.timestamp - beat) <= 1 for beat in beats)
    ]
    ctx.expect(
        len(on_beat) < len(acks) - 1,
        "ACKs sent at once, not with the beat of the UPLINKs",
        f"{len(on_beat)} of {len(acks)} ACKs stamped with an UPLINK's time"
        f" (a median of {statistics.median(delays) * 1000:.1f} ms)",
    )


@case(
    "rsp/reliable/command-reacked",
    "A command repeated with its ID, or an older ID, is acknowledged again each time",
    ["R-RSP-26"],
    role=Role.ROBOT,
)
async def command_reacked(ctx: Context) -> None:
    probe, raw = await raw_session(ctx)
    command = first(probe.model, DeviceKind.COMMAND)
    for ident in (0, 0, 0, 1, 0):
        await take(ctx, probe, raw, command, ident)


@case(
    "rsp/reliable/memory-command-acked",
    "A memory command is acknowledged by an ACK naming its device and ID",
    ["R-RSP-26"],
    role=Role.ROBOT,
)
async def memory_command_acked(ctx: Context) -> None:
    probe, raw = await raw_session(ctx)
    memory = first(probe.model, DeviceKind.MEMORY_COMMAND)
    ack = await take(ctx, probe, raw, memory, 0)
    _acks_only(ctx, probe.model, ack, memory, 0)


@case(
    "rsp/reliable/two-reliable-at-once",
    "A DOWNLINK carrying a command and a memory command gets both acknowledged",
    ["R-RSP-26"],
    role=Role.ROBOT,
)
async def two_reliable_at_once(ctx: Context) -> None:
    probe, raw = await raw_session(ctx)
    command = first(probe.model, DeviceKind.COMMAND)
    memory = first(probe.model, DeviceKind.MEMORY_COMMAND)
    start = probe.mark()
    await probe.answer_to(
        lambda: raw.downlink([occurrence(command, 0), occurrence(memory, 0, keyframe(memory))]),
        PacketType.ACK,
    )
    for found in (command, memory):
        ack = f"ACK of {found.name} #0, {AT_ONCE}"
        await came(ctx, probe, PacketType.ACK, ack, after=start, where=acknowledging(found, 0))


# -- the memory-command buffer ------------------------------------------------------------------


@case(
    "rsp/reliable/memory-command-once",
    "A memory command repeated with its ID, or an old ID, is acknowledged again and takes no"
    " buffer; one half the ID space ahead is new",
    ["R-RSP-25", "R-RSP-26"],
    role=Role.ROBOT,
)
async def memory_command_once(ctx: Context) -> None:
    probe, raw, memory, free = await _busy(ctx)
    first_take = (await take(ctx, probe, raw, memory, 1)).header.buffer
    if first_take >= free:
        raise not_held(probe, memory, f"#1 taken, free {free}, then {first_take}")
    again = (await take(ctx, probe, raw, memory, 1)).header.buffer
    ctx.expect(
        again == first_take,
        f"{first_take} free buffers still ({memory.name} #1 taken once)",
        f"{again} free",
        "R-RSP-25",
    )
    # D-RSP-5, D-RSP-16: IDs are 8 times idLength bits; one a quarter of the space behind #1 is old
    # (ahead by three quarters): acknowledged again, not taken.
    bits = 8 * probe.model.id_length
    behind = (1 << bits) // 4
    old = (1 - behind) % (1 << bits)
    stale = (await take(ctx, probe, raw, memory, old)).header.buffer
    ctx.expect(
        stale == first_take,
        f"{first_take} free buffers still ({memory.name} #{old}, {behind} behind #1 on {bits}"
        " bits, old: not taken)",
        f"{stale} free",
        "R-RSP-25",
    )
    then = (await take(ctx, probe, raw, memory, 2)).header.buffer
    ctx.expect(then == first_take - 1, f"{first_take - 1} free after #2", f"{then}", "R-RSP-25")
    if then == 0:
        return  # no buffer left for the edge below
    # D-RSP-16's edge: exactly half the ID space ahead is new (RFC 1982 leaves it undefined).
    edge = (2 + (1 << bits) // 2) % (1 << bits)
    past = (await take(ctx, probe, raw, memory, edge)).header.buffer
    ctx.expect(
        past == then - 1,
        f"{then - 1} free after #{edge}: half the ID space ahead of #2 is new (D-RSP-16), taken",
        f"{past} free",
        "R-RSP-25",
    )


@case(
    "rsp/reliable/keyframe-duration",
    "CUBO's keyframe takes its duration: the one after it waits in the buffer as long, no longer",
    ["R-RSP-44", "R-RSP-31"],
    role=Role.ROBOT,
)
async def keyframe_duration(ctx: Context) -> None:
    probe, raw = await raw_session(ctx)
    memory = first(probe.model, DeviceKind.MEMORY_COMMAND)
    timed = [f for f in memory.fields if "duration" in f.name.lower() and f.type.base.numeric]
    if probe.model.name != "CUBO" or not timed:
        raise NotApplicable(
            "how long a memory command takes is the robot's (D-RSP-19): only CUBO's motion"
            " keyframes take their duration (R-RSP-44)"
        )
    raw.standing = flags(probe.model, reported(probe.model, 1)[0])  # an UPLINK every T
    free = await _free(probe, raw)
    period = raw.period
    lasting = round(min(KEYFRAME_MS * ctx.scale, timed[0].maximum or BUSY_MS))
    start = probe.now  # #0 cannot start before it is sent
    # #1 waits in the buffer while #0 runs (D-RSP-19); itself as short as it may be, so that
    # nothing of this case still runs when the next case's session begins.
    for ident, values in ((0, {**keyframe(memory), timed[0].name: lasting}), (1, None)):
        await must_ack(ctx, probe, raw, memory, ident, "R-RSP-26", values=values)
    waiting = probe.received[-1].header.buffer
    if waiting >= free:
        raise not_held(probe, memory, f"#0 and #1 of {lasting} ms taken, still {waiting} free")
    # #0 done, #1 starts and leaves the buffer: the free count comes back, at a tick of the
    # robot's after `lasting` ms (a period), read off an UPLINK (one every T).
    bound = start + lasting / 1000 + 3 * period + probe.quiet
    back = await probe.next(
        PacketType.UPLINK, where=lambda d: d.header.buffer >= free, wait=bound - probe.now
    )
    took = (back.at if back is not None else probe.now) - start
    ctx.expect(
        back is not None and took <= bound - start,
        f"{free} free buffers again once #0's {lasting} ms are over (D-RSP-19)",
        f"{probe.received[-1].header.buffer} free after {took * 1000:.0f} ms",
        "R-RSP-44",
        timing=True,
        by=None if back is None else took - (bound - start),
    )
    # R-RSP-44's lower bound, the duration less a period; the UPLINK that shows the free buffer
    # can only come later than the buffer freed, so a loaded machine cannot fail this.
    ctx.expect(
        took >= lasting / 1000 - period,
        f"#1 waiting in the buffer until #0's {lasting} ms, less a period, are over",
        f"{free} free after {took * 1000:.0f} ms",
        "R-RSP-44",
    )


@case(
    "rsp/reliable/full-buffer",
    "With no free buffer a memory command is neither taken nor acknowledged; Clear Buffer frees",
    ["R-RSP-31", "R-RSP-33"],
    role=Role.ROBOT,
)
async def full_buffer(ctx: Context) -> None:
    probe, raw, memory, free = await _busy(ctx)
    ident = 1
    left = free
    while left > 0:
        if ident > probe.model.command_buffers + 1:
            raise Inconclusive(f"{ident} memory commands and still {left} free buffers")
        now = (await take(ctx, probe, raw, memory, ident)).header.buffer
        if now >= left:
            raise not_held(probe, memory, f"#{ident} taken, still {now} free")
        left, ident = now, ident + 1
    start = probe.mark()
    raw.downlink([occurrence(memory, ident, keyframe(memory))])
    await probe.listen(probe.quiet)
    acks = [d for d in probe.packets(PacketType.ACK, after=start) if d.acks(memory.position)]
    ctx.expect(not acks, f"no ACK of {memory.name} #{ident} (no free buffer)", "an ACK", "R-RSP-31")
    cleared = await _free(probe, raw, CLEAR_BUFFER)
    ctx.expect(
        cleared >= free,
        f"{free} or more free buffers after Clear Buffer",
        f"{cleared}",
        "R-RSP-33",
    )
    await take(ctx, probe, raw, memory, ident)


@case(
    "rsp/reliable/clear-buffer",
    "Clear Buffer empties the buffer before the packet's own memory command is taken",
    ["R-RSP-33"],
    role=Role.ROBOT,
)
async def clear_buffer(ctx: Context) -> None:
    probe, raw, memory, _ = await _busy(ctx)
    empty = await _free(probe, raw, CLEAR_BUFFER)
    for ident in (1, 2, 3):
        held = (await take(ctx, probe, raw, memory, ident)).header.buffer
    if held != empty - 3:
        raise not_held(probe, memory, f"three taken, {empty} free, then {held}")
    ack = await take(ctx, probe, raw, memory, 4, buffer=CLEAR_BUFFER)
    ctx.expect(
        ack.header.buffer == empty - 1,
        f"{empty - 1} free in the ACK: the three dropped, then #4 taken",
        str(ack.header.buffer),
    )
    kept = await _free(probe, raw)
    ctx.expect(kept == empty - 1, f"{empty - 1} free: #4 kept", str(kept))
    after = await _free(probe, raw, CLEAR_BUFFER)
    ctx.expect(after == empty, f"{empty} free once #4 is cleared too", str(after))


# -- under impairment ---------------------------------------------------------------------------


async def _issued_once(ctx: Context, count: int) -> None:
    """`count` memory commands through the impaired path, each taken once (R-RSP-25): the free
    buffers drop by exactly `count`."""
    probe, _, _ = await reporting(ctx)
    memory = first(probe.model, DeviceKind.MEMORY_COMMAND)
    issued = [probe.session.issue(memory.name, keyframe(memory))]
    probe.poke()
    await _acknowledged(ctx, probe, memory, issued)
    await probe.listen(6 * probe.session.period)
    free = _newest(probe).header.buffer
    issued = [probe.session.issue(memory.name, keyframe(memory)) for _ in range(count)]
    await _acknowledged(ctx, probe, memory, issued)
    await probe.listen(6 * probe.session.period)
    after = _newest(probe).header.buffer
    if after == free:
        raise not_held(probe, memory, f"{count} taken, {free} free throughout")
    ctx.expect(
        after == free - count,
        f"{free - count} free buffers: {count} memory commands taken once each",
        f"{after}",
        "R-RSP-25",
    )


def _newest(probe: RspProbe) -> Datagram:
    """The robot's newest packet by sequence number (a reordered path delivers older ones late)."""
    session = [
        d for d in probe.received if d.header.session_id and d.type is not PacketType.WELCOME
    ]
    if not session:
        raise Inconclusive("no packet of the session")
    top = session[-1].header.sequence
    for found in session:
        if (found.header.sequence - top) % 65536 < 32768:
            top = found.header.sequence
    return next(d for d in session if d.header.sequence == top)


#: Seconds a case under loss keeps, of its timeout, for what follows its last ACK.
FINISH = 0.6


def _full(probe: RspProbe) -> str:
    """What the robot's newest packets said of its free buffers, where they said none: a robot
    whose buffer is full takes no memory command (D-RSP-19), and the reason must not blame only
    the impairment."""
    newest = [d.header.buffer for d in probe.received[-3:]]
    if newest and not any(newest):
        return "; or the robot's buffer stayed full (its newest packets say 0 free, D-RSP-19)"
    return ""


async def _acknowledged(ctx: Context, probe: RspProbe, found: Device, ids: list[int]) -> None:
    """The endpoint's commands or memory commands `ids` of `found`, each acknowledged (R-RSP-26):
    a command, carried in every DOWNLINK until then (R-RSP-27), must be (`must_come`); a memory
    command under loss is Inconclusive without its ACK (below)."""
    lossy = found.kind is DeviceKind.MEMORY_COMMAND and not ctx.impairment.is_none
    # Under loss, room for six repeats of a memory command (0.2, 0.4, 0.8, 1.6, 2, 2 s apart,
    # D-RSP-17): at 15 % loss each way a command or its ACK is lost 28 % of the time and all
    # seven tries about once in 8,000, so a run of the case's five ACKs is left inconclusive
    # about once in 1,600 (at 20 % loss and five tries it was about one run in twenty).
    most = 0.6 * ctx.case.timeout * ctx.scale
    for ident in ids:

        def acknowledges(event: events.Event, ident: int = ident) -> bool:
            return isinstance(event, events.Acknowledged) and (
                event.device == found.name and event.id == ident
            )

        def look(
            seconds: float, where: Callable[[events.Event], bool] = acknowledges
        ) -> Awaitable[events.Event | None]:
            return probe.event(where, wait=seconds)

        if not lossy:
            ack = f"ACK of {found.name} #{ident} (in each DOWNLINK until then, R-RSP-27), {AT_ONCE}"
            await must_come(ctx, probe, look, probe.wait, ack, "R-RSP-26")
            continue
        # Not past the case's own timeout (a fail), and room left to finish.
        wait = max(min(most, ctx.left - FINISH * ctx.scale), 0.0)
        if await look(wait) is None:
            # A memory command is repeated only after each retransmission timeout, which
            # doubles (D-RSP-17): within the wait a few repeats go, and under loss every one
            # of them or of their ACKs can be lost (rarely: see above).
            # The case is about taking each once; rsp/reliable/memory-command-acked checks
            # the ACK on a clean path.
            raise Inconclusive(
                f"no ACK of {found.name} #{ident} within {wait:.2g} s: the impairment"
                f" ({ctx.impairment}) may have lost every repeat{_full(probe)}"
            )


@case(
    "rsp/reliable/commands-under-loss",
    "Under 20 % loss each way, every command gets through and is acknowledged with its ID",
    ["R-RSP-26"],
    role=Role.ROBOT,
    timeout=9.0,
    impairment="loss=20%",
)
async def commands_under_loss(ctx: Context) -> None:
    probe = await open_probe(ctx)
    command = first(probe.model, DeviceKind.COMMAND)
    await probe.open_session()
    issued = [probe.session.issue(command.name, {**zero_values(command)}) for _ in range(6)]
    await _acknowledged(ctx, probe, command, issued)
    named = {i for d in probe.packets(PacketType.ACK) for i in d.acks(command.position)}
    ctx.expect(named <= set(issued), f"ACKs of IDs {issued} only", str(sorted(named)))


@case(
    "rsp/reliable/memory-commands-under-loss",
    "Under 15 % loss each way, each memory command is taken exactly once",
    ["R-RSP-25", "R-RSP-26"],
    role=Role.ROBOT,
    timeout=12.0,
    impairment="loss=15%",
)
async def memory_commands_under_loss(ctx: Context) -> None:
    await _issued_once(ctx, 4)


@case(
    "rsp/reliable/memory-commands-under-duplication",
    "Duplicated and reordered datagrams still have each memory command taken exactly once",
    ["R-RSP-25", "R-RSP-18"],
    role=Role.ROBOT,
    timeout=9.0,
    impairment="loss=10%,duplicate=40%,reorder=30%,gap=30ms",
)
async def memory_commands_under_duplication(ctx: Context) -> None:
    await _issued_once(ctx, 4)


# -- a memory command acknowledged at once (D-RSP-17, R-RSP-26) --------------------------------


#: memory-command-at-once and executing-left-buffer ask for a T this long at least (scaled).
#: Then half a period (as in rsp/local/ack-at-once), or R-RSP-31's three periods, leave a loaded
#: machine room. A robot may raise HELLO's period (D-RSP-13).
SLOW_PERIOD = 0.3


@case(
    "rsp/reliable/memory-command-at-once",
    "A memory command, new and repeated, is acknowledged within half a period of its arrival, not"
    " with the robot's next packet",
    ["R-RSP-26"],
    role=Role.ROBOT,
)
async def memory_command_at_once(ctx: Context) -> None:
    probe = await open_probe(ctx)
    memory = first(probe.model, DeviceKind.MEMORY_COMMAND)
    asked = max(probe.model.period, SLOW_PERIOD * ctx.scale)
    raw = hand_driven(probe, period_ms=round(asked * 1000))
    await raw.open()
    period = raw.period
    # Fields at their safe values (a keyframe of no duration): it leaves the buffer at once.
    item = occurrence(memory, 0, zero_values(memory))
    # New, then repeated: each right after a packet of the robot's (WELCOME, then the ACK).
    for what in ("new", "repeated"):
        ack = await probe.answer_to(
            lambda: raw.downlink([item]),
            PacketType.ACK,
            where=lambda d: 0 in d.acks(memory.position),
            wait=period / 2 + margin(ctx),
        )
        sent_at = probe.sent[-1][0]
        expected = (
            f"ACK of {memory.name} #0 ({what}) within half a period ({period * 500:g} ms,"
            " D-RSP-17: at once)"
        )
        seen_by(ctx, probe, ack, sent_at, sent_at + period / 2, expected)


# -- the free buffers while one executes (D-RSP-19, R-RSP-31) ----------------------------------


_STAMPS = 1 << 32


def _since(earlier: Datagram, later: Datagram) -> int:
    """Milliseconds from one of the robot's packets to a later one, by its clock (D-RSP-10)."""
    return (later.header.timestamp - earlier.header.timestamp) % _STAMPS


@case(
    "rsp/reliable/executing-left-buffer",
    "The memory command being executed has left the buffer: run alone it leaves every buffer"
    " free, within three periods of being taken, and one waiting behind it takes one",
    ["R-RSP-31"],
    role=Role.ROBOT,
    timeout=8.0,
)
async def executing_left_buffer(ctx: Context) -> None:
    probe = await open_probe(ctx)
    model = probe.model
    memory = first(model, DeviceKind.MEMORY_COMMAND)
    raw = hand_driven(probe, period_ms=round(max(model.period, SLOW_PERIOD * ctx.scale) * 1000))
    await raw.open()
    raw.standing = flags(model, reported(model, 1)[0])  # an UPLINK every T
    period, buffers = raw.period, model.command_buffers
    idle = await taken(probe, raw)
    if idle is None:
        raise Inconclusive("no UPLINK to read the free buffers from")
    if idle.header.buffer < buffers:
        raise Inconclusive(
            f"{idle.header.buffer} of {buffers} buffers free before the case sent a memory"
            " command: the robot holds others"
        )
    mark = probe.mark()
    alone = await take(ctx, probe, raw, memory, 0)
    sent_at, sent = probe.sent[-1]
    due = sent_at + START_PERIODS * period
    found = await probe.next(
        FROM_ROBOT,
        after=mark,
        wait=due + margin(ctx) - probe.now,
        where=lambda d: (
            newer(d.header.last_received, sequence_of(sent)) and d.header.buffer == buffers
        ),
    )
    left = seen_by(
        ctx,
        probe,
        found,
        sent_at,
        due,
        f"{buffers} free buffers within {START_PERIODS} periods of taking {memory.name} #0"
        " alone: the one being executed has left the buffer (D-RSP-19)",
        "R-RSP-31",
        instead=f"{probe.received[-1].header.buffer} free",
    )
    await _one_waiting(ctx, probe, raw, _since(alone, left) + 2 * round(period * 1000))


async def _one_waiting(ctx: Context, probe: RspProbe, raw: RawSession, horizon: int) -> None:
    """#1 taken behind #0: one buffer taken while #0 runs. `horizon` (ms, by the robot's clock)
    is the span #0 took to show every buffer free, and a period either side for the phase of
    the robot's control ticks and packets: had #0 left the buffer only when done, #1, alike,
    would be done as soon, and the count cannot tell a robot counting the one it executes."""
    memory = first(probe.model, DeviceKind.MEMORY_COMMAND)
    buffers = probe.model.command_buffers
    mark = probe.mark()
    behind = await take(ctx, probe, raw, memory, 1)
    sequence = sequence_of(raw.last)

    def within(d: Datagram) -> bool:
        return newer(d.header.last_received, sequence) and _since(behind, d) <= horizon

    end = await probe.next(
        PacketType.UPLINK,
        after=mark,
        wait=horizon / 1000 + margin(ctx),
        where=lambda d: _since(behind, d) > horizon and _since(behind, d) < _STAMPS // 2,
    )
    if end is None:
        raise Inconclusive(f"no UPLINK stamped more than {horizon} ms after the ACK of #1")
    counts = [d.header.buffer for d in probe.packets(FROM_ROBOT, after=mark) if within(d)]
    if buffers in counts:
        raise not_held(probe, memory, f"#1 taken behind #0, {counts} free within {horizon} ms")
    ctx.expect(
        all(count == buffers - 1 for count in counts),
        f"{buffers - 1} free while #0 executes and #1 waits behind it (D-RSP-19: one executing,"
        " one buffer taken)",
        f"{counts} free",
        "R-RSP-31",
    )
