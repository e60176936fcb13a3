"""rsp/local, receiving: what an RSP local system under test does with the robot's packets that it
must drop or ignore (R-RSP-18, R-RSP-19, R-RCML-30 on the local side), an event of an old ID it
must not take again (R-RSP-25), and how soon it acknowledges a memory event (R-RSP-26). The
harness plays the robot (`--role local`).

The conformance scenario (D-RSP-24) makes taking a packet visible on the wire: a memory event the
local system receives is acknowledged at once, new or repeated (R-RSP-26); an ACK of its command
ends that command's ride in every DOWNLINK (D-RSP-17); the robot's newest free-buffer count lets
its memory commands go or holds them (D-RSP-19). So each case sends, as the robot, a packet the
local system must not act on — naming another session, a byte after its payloads, a bool byte of
2, seen before, 65 behind the newest, a late one whose buffer byte is older than the newest, a
DOWNLINK (a type it is not sent, D-RSP-11) naming its command as the command's ACK would — and
checks that nothing of it shows; then it sends the same thing as a robot may, and checks that it
shows: a local system that takes nothing passes none of these cases.

A clean start for every case. A local system runs one session at a time, so a case can have one
only once the local system is done with the one the case before ended (BYE, R-RSP-22). One that
goes on with it (it ignored the BYE) is caught by rsp/local/bye-ends; the cases after it must not
wait in vain for its next HELLO: the runner starts a local case's clock only once the local system
is free (`LocalListener.settled`: a new HELLO came, or the old session's BYE, or its run is over by
D-RSP-24 step 5, 10 s after WELCOME), as a robot case waits for a free robot. What the old session
sent after the BYE is noted in the transcript of the case that waited.
"""

from __future__ import annotations

import asyncio
import math
from collections.abc import Callable

from rcmlconf.conformance.cases.rsp_local.session import (
    carries,
    ids,
    local_case,
    numbered,
    occurrence,
    played_model,
    sent_after,
    session,
)
from rcmlconf.conformance.context import Context
from rcmlconf.conformance.probes.held import margin, seen_by
from rcmlconf.conformance.probes.local_probe import LocalProbe
from rcmlconf.conformance.probes.rsp_datagram import Datagram, sequence_of
from rcmlconf.conformance.probes.rsp_devices import first, zero_values
from rcmlconf.conformance.probes.rsp_forged import patch
from rcmlconf.conformance.rsp_numbers import unheard_for
from rcmlconf.conformance.verdicts import Inconclusive, NotApplicable
from rcmlconf.rsp.codec import Encryption, Header, Item, MapBody, PacketType, Period
from rcmlconf.rsp.model import Device, DeviceKind, Field, RobotModel
from rcmlconf.values import Value
from rcmlconf.values.types import Kind

#: What the robot reports in an UPLINK (D-RSP-14): where a bool field can ride.
_REPORTED = (DeviceKind.SENSOR, DeviceKind.MONITOR, DeviceKind.EVENT, DeviceKind.MEMORY_EVENT)
_OCCURRENCES = (DeviceKind.EVENT, DeviceKind.MEMORY_EVENT)
#: rsp/local/ack-at-once asks for a T this long at least (scaled), so that R-RSP-26's half a
#: period leaves a loaded machine room: a robot may raise HELLO's period (D-RSP-13).
ACK_AT_ONCE_PERIOD = 0.3
#: A late UPLINK's place behind the newest: the window's edge (D-RSP-15: 64 read, 65 dropped).
INSIDE, OUTSIDE = 64, 65


def silence(probe: LocalProbe) -> float:
    """How long no ACK says a packet was not taken: an ACK goes within half a period (R-RSP-26,
    D-RSP-17), so two periods, and the probe's quiet time at least."""
    return max(probe.quiet, 2 * probe.period)


def acks(device: Device, ident: int) -> Callable[[Datagram], bool]:
    return lambda found: ident in found.acks(device.position)


async def dropped_then_taken(
    ctx: Context,
    probe: LocalProbe,
    memory: Device,
    drop: Callable[[], object],
    what: str,
    take: Callable[[], object],
    well: str,
    requirement: str = "R-RSP-18",
) -> None:
    """`drop` sends `memory` #0 in a packet the local system must drop (`what`): no ACK of it
    may come. Then `take` sends it as a robot may (`well`): its ACK must (R-RSP-26), which shows
    that the first was dropped for what was wrong with it."""
    mark = probe.mark()
    if not probe.send_intact(drop):
        raise Inconclusive(f"the impairment spoiled every copy of {what}")
    ack = await probe.next(PacketType.ACK, after=mark, wait=silence(probe), where=acks(memory, 0))
    ctx.expect(
        ack is None,
        f"{what} dropped unread: no ACK of its {memory.name} #0",
        f"ACK #{ack.header.sequence} of it" if ack is not None else "",
        requirement,
    )
    await taken(ctx, probe, memory, take, well)


async def taken(
    ctx: Context, probe: LocalProbe, memory: Device, send: Callable[[], object], what: str
) -> None:
    """`send` sends `memory` #0 as a robot may (`what`): its ACK must come (R-RSP-26), within
    `silence`: a timing check, which the harness's holds excuse as far as they add up to how
    late the ACK came (none at all in as long again: any hold, D-RSP-26)."""
    start, at, bound = probe.mark(), probe.now, silence(probe)
    ack = await probe.answer_to(send, PacketType.ACK, where=acks(memory, 0), wait=bound)
    if ack is not None:
        return
    late = await probe.next(PacketType.ACK, after=start, where=acks(memory, 0), wait=bound)
    ctx.expect(
        False,
        f"{what} acknowledged (R-RSP-26: a memory event, new or repeated)",
        f"no ACK of {memory.name} #0 within {bound * 1000:.0f} ms"
        + (f" (one {(late.at - at) * 1000:.0f} ms after)" if late is not None else ""),
        "R-RSP-26",
        timing=True,
        by=late.at - at - bound if late is not None else None,
    )


async def malformed_then_taken(
    ctx: Context,
    probe: LocalProbe,
    memory: Device,
    items: tuple[Item, ...],
    what: str,
    *,
    session_id: int | None = None,
    alter: Callable[[bytes], bytes] | None = None,
    via: Callable[[bytes], object] | None = None,
    requirement: str = "R-RSP-18",
) -> None:
    """An UPLINK of `items`, `memory` #0 among them, made one the local system must drop
    (`LocalProbe.forged`), then the same well-formed (`dropped_then_taken`)."""
    await dropped_then_taken(
        ctx,
        probe,
        memory,
        lambda: probe.forged(
            PacketType.UPLINK, MapBody(items), what, session_id=session_id, alter=alter, via=via
        ),
        what,
        lambda: probe.uplink(items),
        "the same well-formed",
        requirement,
    )


def at_sequence(probe: LocalProbe, behind: int, items: list[Item]) -> bytes:
    """An UPLINK of `items` numbered `behind` before the newest the probe sent, never sent
    before (a late packet, D-RSP-15); the probe's numbering goes on after its newest."""
    wire = probe.wire
    assert wire is not None
    resume = wire.sent
    wire.sent = resume - 1 - behind
    try:
        return probe.uplink(items)
    finally:
        wire.sent = resume


def jump(probe: LocalProbe, packets: int) -> None:
    """An empty UPLINK `packets` further on than the probe's next number, the newest the local
    system has (as if that many had been lost), sent again while the impairment spoils it."""
    wire = probe.wire
    assert wire is not None
    wire.sent += packets
    intact(probe, probe.uplink, f"the UPLINK {packets} ahead")


def intact(probe: LocalProbe, send: Callable[[], bytes], what: str) -> bytes:
    """`send` (it sends one packet and returns it), again while the case's impairment spoils
    it; the last sent."""
    sent: list[bytes] = []
    if not probe.send_intact(lambda: sent.append(send())):
        raise Inconclusive(f"the impairment spoiled every copy of {what}")
    return sent[-1]


# -- R-RSP-15: the newest, by serial arithmetic ----------------------------------------------------


@local_case(
    "rsp/local/robot-sequence-wraps",
    "The local system's last received follows the robot's numbers across 65,535 to 0",
    ["R-RSP-15"],
)
async def robot_sequence_wraps(ctx: Context) -> None:
    reliable = (DeviceKind.COMMAND, DeviceKind.MEMORY_COMMAND)
    # Nothing acknowledged and no keep-alive: the robot's numbers move only as the case says.
    withheld = [d for d in played_model(ctx).devices if d.kind in reliable]
    probe = await session(ctx, withheld=withheld, beating=False)
    wire = probe.wire
    assert wire is not None
    # Each 20,000 or fewer ahead of the one before: newer (D-RSP-15), the last past 65,535.
    for index in (20000, 40000, 60000, 65535, 65537):
        wire.sent = index
        number = sequence_of(intact(probe, probe.uplink, f"UPLINK #{index % 65536}"))

        def says(found: Datagram, number: int = number) -> bool:
            return found.header.last_received == number

        sent = probe.now
        due = sent + max(probe.quiet, 4 * probe.period)
        found = await probe.next(PacketType.DOWNLINK, wait=due + margin(ctx) - sent, where=says)
        downlinks = probe.packets(PacketType.DOWNLINK)
        seen_by(
            ctx,
            probe,
            found,
            sent,
            due,
            f"a DOWNLINK saying last received {number}: the newest, by serial arithmetic"
            " (D-RSP-15)",
            instead=f"last received {downlinks[-1].header.last_received}" if downlinks else "",
        )


# -- R-RSP-18: dropped unread --------------------------------------------------------------------


@local_case(
    "rsp/local/other-session-dropped",
    "An UPLINK naming another session ID is dropped: its memory event is not acknowledged",
    ["R-RSP-18", "R-RSP-26"],
)
async def other_session_dropped(ctx: Context) -> None:
    memory = first(played_model(ctx), DeviceKind.MEMORY_EVENT)
    probe = await session(ctx)
    other = probe.session_id ^ 1 or 2
    await malformed_then_taken(
        ctx,
        probe,
        memory,
        (occurrence(memory, 0),),
        f"an UPLINK naming session {other:#x}, not {probe.session_id:#x}",
        session_id=other,
    )


@local_case(
    "rsp/local/other-address-dropped",
    "An UPLINK of the session from another port is dropped; from the robot's, it is taken",
    ["R-RSP-18", "R-RSP-26"],
)
async def other_address_dropped(ctx: Context) -> None:
    memory = first(played_model(ctx), DeviceKind.MEMORY_EVENT)
    probe = await session(ctx)
    host, robot_port = probe.listener.address
    loop = asyncio.get_running_loop()
    # D-RSP-12: a session's packets come from the one address; this socket is another port of it.
    other, _ = await loop.create_datagram_endpoint(asyncio.DatagramProtocol, local_addr=(host, 0))
    ctx.on_close(other.close)
    port = other.get_extra_info("sockname")[1]
    await malformed_then_taken(
        ctx,
        probe,
        memory,
        (occurrence(memory, 0),),
        f"an UPLINK of the session from port {port}, not the robot's {robot_port}",
        via=lambda data: other.sendto(data, probe.peer),
    )


@local_case(
    "rsp/local/trailing-bytes-dropped",
    "An UPLINK or an ACK with a byte after its payloads is dropped; well-formed, each is taken",
    ["R-RSP-18", "R-RSP-16", "R-RSP-27"],
)
async def trailing_bytes_dropped(ctx: Context) -> None:
    model = played_model(ctx)
    memory = first(model, DeviceKind.MEMORY_EVENT)
    command = first(model, DeviceKind.COMMAND)
    probe = await session(ctx, withheld=[command])
    ident = await _in_flight(probe, command)

    def longer(body: bytes) -> bytes:
        return body + b"\x00"

    what = f"an ACK of {command.name} #{ident} with a byte after it"
    await _acknowledged_only_by_ack(
        ctx,
        probe,
        command,
        ident,
        lambda: probe.forged(
            PacketType.ACK, MapBody((Item(command.position, ident),)), what, alter=longer
        ),
        what,
        "the ACK with a byte after its IDs dropped",
    )
    await malformed_then_taken(
        ctx,
        probe,
        memory,
        (occurrence(memory, 0),),
        "an UPLINK with a byte after its payloads",
        alter=longer,
    )


@local_case(
    "rsp/local/downlink-dropped",
    "A DOWNLINK from the robot is dropped: one naming the command in flight does not ACK it",
    ["R-RSP-18", "R-RSP-27"],
)
async def downlink_dropped(ctx: Context) -> None:
    command = first(played_model(ctx), DeviceKind.COMMAND)
    probe = await session(ctx, withheld=[command])
    ident = await _in_flight(probe, command)
    # D-RSP-11: a type the local system is not sent is malformed, though a DOWNLINK of the
    # command reads as its ACK would (Device Map, then the ID), and well-formed else.
    what = f"a DOWNLINK naming {command.name} #{ident}, as its ACK would"
    body = MapBody((occurrence(command, ident),))

    def downlink() -> bytes:
        free, probe.free = probe.free, 0  # a DOWNLINK's buffer byte: no Clear Buffer (D-RSP-10)
        try:
            return probe.forged(PacketType.DOWNLINK, body, what)
        finally:
            probe.free = free

    await _acknowledged_only_by_ack(
        ctx,
        probe,
        command,
        ident,
        downlink,
        what,
        "the DOWNLINK dropped: a type the local system is not sent (D-RSP-11)",
    )


async def _in_flight(probe: LocalProbe, command: Device) -> int:
    """The ID of the scenario's `command` (D-RSP-24 step 2), which the probe does not
    acknowledge, once it has ridden every DOWNLINK for three periods; Inconclusive if it did not
    (R-RSP-27, which rsp/local/command-until-acked checks)."""
    carrying = await probe.next(PacketType.DOWNLINK, after=0, where=carries(command))
    found = carrying.item(command.position) if carrying is not None else None
    if found is None or found.id is None:
        raise Inconclusive(f"no {command.name} command issued (D-RSP-24 step 2)")
    ident = found.id
    await probe.listen(3 * probe.period)
    if not all(map(carries(command, ident), probe.packets(PacketType.DOWNLINK, after=0))):
        raise Inconclusive(
            f"{command.name} #{ident} not in every DOWNLINK before its ACK: R-RSP-27, which"
            " rsp/local/command-until-acked checks"
        )
    return ident


async def _acknowledged_only_by_ack(
    ctx: Context,
    probe: LocalProbe,
    command: Device,
    ident: int,
    send: Callable[[], bytes],
    what: str,
    dropped: str,
) -> None:
    """`send` sends a packet naming `command` #`ident` that the local system must drop
    (`what`, R-RSP-18): the command must still ride every DOWNLINK. Then its well-formed ACK
    must end the ride (R-RSP-27), which shows the first was dropped for what was wrong with it."""
    bad = intact(probe, send, what)
    riding = await _downlinks_after(ctx, probe, bad)
    gone = [d for d in riding if not carries(command, ident)(d)]
    ctx.expect(
        not gone,
        f"{dropped}: {command.name} #{ident} in every DOWNLINK",
        f"not in DOWNLINK #{gone[0].header.sequence}" if gone else "",
        "R-RSP-18",
    )
    good = intact(probe, lambda: probe.ack([Item(command.position, ident)]), "the ACK")
    still = [d for d in await _downlinks_after(ctx, probe, good) if carries(command, ident)(d)]
    ctx.expect(
        not still,
        f"the well-formed ACK taken: {command.name} #{ident} no more",
        f"in DOWNLINK #{still[0].header.sequence}" if still else "",
        "R-RSP-27",
    )


async def _downlinks_after(ctx: Context, probe: LocalProbe, sent: bytes) -> list[Datagram]:
    """The DOWNLINKs of two periods past D-RSP-26's bound sent after the local system had
    `sent`; Inconclusive if none came (D-RSP-13: one every T)."""
    at = probe.now
    wait = unheard_for(probe.period, ctx.scale) + 2 * probe.period
    later = await probe.received_within(wait, PacketType.DOWNLINK)
    heard = sent_after(ctx, probe, sent, at)
    found = [d for d in later if heard(d)]
    if not found:
        raise Inconclusive(f"no DOWNLINK after #{sequence_of(sent)} within {wait:.2f} s")
    return found


@local_case(
    "rsp/local/bad-bool-dropped",
    "An UPLINK with a bool byte of 2 is malformed and dropped; with 1 it is taken",
    ["R-RSP-18", "R-RCML-30", "R-RSP-26"],
)
async def bad_bool_dropped(ctx: Context) -> None:
    model = played_model(ctx)
    memory = first(model, DeviceKind.MEMORY_EVENT)
    device, flag = _with_bool(model)
    probe = await session(ctx)
    header = Header(1, model.model_id, Encryption.NONE, PacketType.UPLINK, 0, 0, 0, 0, 0)
    off, on = (
        probe.codec.push_body(header, MapBody(_reporting(memory, device, flag, value)))
        for value in (False, True)
    )
    at = next(i for i, (a, b) in enumerate(zip(off, on, strict=True)) if a != b)
    await malformed_then_taken(
        ctx,
        probe,
        memory,
        _reporting(memory, device, flag, True),
        f"an UPLINK whose bool {device.name}.{flag.name} is the byte 0x02, not 0x01 (D-RCML-10)",
        alter=lambda body: patch(body, at, b"\x02"),
        requirement="R-RCML-30",
    )


def _with_bool(model: RobotModel) -> tuple[Device, Field]:
    """The first device an UPLINK reports with a bool field, and the field."""
    for device in model.devices:
        if device.kind in _REPORTED:
            for found in device.fields:
                if found.type.base.kind is Kind.BOOL:
                    return device, found
    raise NotApplicable(f"{model.name} reports no bool field in an UPLINK")


def _reporting(memory: Device, device: Device, flag: Field, on: bool) -> tuple[Item, ...]:
    """`memory` #0, and `device` with `flag` `on` (every item of an array), in model order."""
    values: dict[str, Value] = zero_values(device)
    values[flag.name] = (on,) * flag.type.count if flag.type.is_array else on
    ident = 0 if device.kind in _OCCURRENCES else None
    items = {  # `device` may be the memory event itself: one item
        memory.position: occurrence(memory, 0),
        device.position: Item(device.position, ident, values),
    }
    return tuple(items[p] for p in sorted(items))


@local_case(
    "rsp/local/replay-dropped",
    "An UPLINK received again byte for byte is dropped; its memory event repeated anew is acked",
    ["R-RSP-18", "R-RSP-26"],
)
async def replay_dropped(ctx: Context) -> None:
    memory = first(played_model(ctx), DeviceKind.MEMORY_EVENT)
    probe = await session(ctx)
    item = occurrence(memory, 0)
    sent: list[bytes] = []
    await taken(ctx, probe, memory, lambda: sent.append(probe.uplink([item])), f"{memory.name} #0")
    original = sent[-1]
    probe.uplink()  # the original one behind the newest now: late, and seen before
    again = f"UPLINK #{sequence_of(original)} received again byte for byte (seen before)"
    await dropped_then_taken(
        ctx,
        probe,
        memory,
        lambda: probe.send(original, again),
        again,
        lambda: probe.uplink([item]),
        f"{memory.name} #0 repeated in a new UPLINK",
    )


@local_case(
    "rsp/local/outside-window-dropped",
    "An UPLINK 65 behind the newest is dropped; one 64 behind, never seen, is handled",
    ["R-RSP-18", "R-RSP-26"],
)
async def outside_window_dropped(ctx: Context) -> None:
    memory = first(played_model(ctx), DeviceKind.MEMORY_EVENT)
    probe = await session(ctx)
    item = occurrence(memory, 0)
    jump(probe, 100)
    await dropped_then_taken(
        ctx,
        probe,
        memory,
        lambda: at_sequence(probe, OUTSIDE, [item]),
        f"an UPLINK {OUTSIDE} behind the newest (more than 64, D-RSP-15)",
        lambda: at_sequence(probe, INSIDE, [item]),  # late: its occurrences handled (D-RSP-15)
        f"{memory.name} #0 in an UPLINK {INSIDE} behind the newest, never seen",
    )


# -- R-RSP-19: a late packet's states ------------------------------------------------------------


@local_case(
    "rsp/local/late-buffer-ignored",
    "A late UPLINK's free buffers are not applied: no memory command while the newest says 0",
    ["R-RSP-19"],
)
async def late_buffer_ignored(ctx: Context) -> None:
    model = played_model(ctx)
    memory = first(model, DeviceKind.MEMORY_COMMAND)
    probe = await session(ctx, free=0, withheld=[memory])
    period = probe.period
    await probe.listen(2 * period)
    if any(carries(memory)(d) for d in probe.packets(PacketType.DOWNLINK)):
        raise Inconclusive(
            f"{memory.name} sent while the robot gives 0 free buffers: R-RSP-32, which"
            " rsp/local/no-free-buffer checks"
        )
    jump(probe, 10)  # the newest: 0 free
    mark = probe.mark()
    probe.free = model.command_buffers
    try:
        late = intact(probe, lambda: at_sequence(probe, 5, []), "the late UPLINK")
    finally:
        probe.free = 0
    sent = await probe.next(
        PacketType.DOWNLINK, after=mark, wait=max(probe.quiet, 3 * period), where=carries(memory)
    )
    ctx.expect(
        sent is None,
        f"UPLINK #{sequence_of(late)}'s {model.command_buffers} free buffers ignored: it is late,"
        f" and the newest says 0 (D-RSP-15)",
        f"{memory.name} in DOWNLINK #{sent.header.sequence}" if sent is not None else "",
    )
    mark = probe.mark()
    probe.free = 1
    intact(probe, probe.uplink, "the UPLINK of 1 free buffer")
    if await probe.next(PacketType.DOWNLINK, after=mark, where=carries(memory)) is None:
        raise Inconclusive(
            f"no {memory.name} sent when a newer UPLINK freed a buffer: whether the late one's"
            " count was applied cannot be seen (D-RSP-24 step 2)"
        )


# -- R-RSP-25: an old occurrence is not taken again ----------------------------------------------

#: How long a case waits for the command that shows an event taken, at most (seconds).
TAKEN_WAIT = 2.0


@local_case(
    "rsp/local/event-old-id",
    "An event whose ID is behind the last taken is not taken again; one half the ID space ahead is",
    ["R-RSP-25"],
)
async def event_old_id(ctx: Context) -> None:
    model = played_model(ctx)
    command = first(model, DeviceKind.COMMAND)
    event = first(model, DeviceKind.EVENT)
    # D-RSP-5, D-RSP-16: IDs are 8 times idLength bits; one is new when ahead of the last taken by 1
    # to half the space. A quarter of the space behind #0 is old: ahead by three quarters.
    space = 1 << (8 * model.id_length)
    old = space - space // 4
    probe = await session(ctx)
    # Each event taken issues one more command (D-RSP-24 step 3), which rides the DOWNLINKs
    # from the one after it was issued (D-RSP-17): a few periods show it.
    shows = max(8 * probe.period, probe.quiet)

    async def issued_for(ident: int, *, taken: bool = True) -> list[int]:
        """The commands issued after `event` #`ident` is sent (the probe acknowledges each).
        Where the event is to be taken, up to TAKEN_WAIT: R-RSP-25 is about taking it, not
        when, and a loaded machine may show the command later than `shows`."""
        before = set(ids(probe.packets(PacketType.DOWNLINK), command))
        probe.uplink([occurrence(event, ident)])
        waited = 0.0
        while True:
            await probe.listen(shows)
            waited += shows
            new = [i for i in ids(probe.packets(PacketType.DOWNLINK), command) if i not in before]
            if new or not taken or waited >= TAKEN_WAIT:
                return new

    if not await issued_for(0):
        raise Inconclusive(
            f"no {command.name} issued for {event.name} #0, the session's first: whether an event"
            " is taken cannot be seen (D-RSP-24 step 3)"
        )
    again = await issued_for(old, taken=False)
    ctx.expect(
        not again,
        f"{event.name} #{old} old: {space // 4} behind #0 on {8 * model.id_length} bits"
        " (D-RSP-16), not taken: no command for it",
        numbered(command, again) if again else "",
    )
    if not await issued_for(1):
        raise Inconclusive(f"no {command.name} issued for {event.name} #1, new after #0")
    # D-RSP-16's other edge: exactly half the space ahead is new (RFC 1982 leaves it undefined).
    edge = (1 + space // 2) % space
    ctx.expect(
        bool(await issued_for(edge)),
        f"{event.name} #{edge} new: half the ID space ahead of #1 (D-RSP-16), taken: one"
        f" {command.name} command for it",
        "no command for it",
    )


# -- R-RSP-26: at once -----------------------------------------------------------------------------


@local_case(
    "rsp/local/ack-at-once",
    "A memory event is acknowledged within half a period, new and repeated, not at the next beat",
    ["R-RSP-26"],
    timeout=6.0,
)
async def ack_at_once(ctx: Context) -> None:
    model = played_model(ctx)
    memory = first(model, DeviceKind.MEMORY_EVENT)
    # A slow T, right after a beat of the local system: an ACK held for its next beat comes
    # most of a period late, one sent at once in a few milliseconds.
    probe = await session(ctx, slower=math.ceil(ACK_AT_ONCE_PERIOD * ctx.scale / model.period))
    period = probe.period
    start = probe.mark()
    if await probe.next(PacketType.DOWNLINK, after=start, wait=2 * period) is None:
        raise Inconclusive(f"no DOWNLINK within two periods ({2 * period * 1000:.0f} ms)")
    await _within_half(ctx, probe, memory, period, f"{memory.name} #0")
    change = await probe.next(PacketType.PERIOD, after=start, wait=2 * period)
    if change is None or not isinstance(change.body, Period):
        raise Inconclusive(f"no PERIOD after {memory.name} #0 (D-RSP-24 step 4)")
    slower = change.body.period_ms / 1000
    beat = (PacketType.DOWNLINK, PacketType.PERIOD)
    if await probe.next(beat, after=probe.mark(), wait=2 * slower) is None:
        raise Inconclusive(f"no PERIOD or DOWNLINK within two periods of {slower * 1000:g} ms")
    await _within_half(ctx, probe, memory, slower, f"{memory.name} #0 repeated")


async def _within_half(
    ctx: Context, probe: LocalProbe, memory: Device, period: float, what: str
) -> None:
    """`memory` #0 sent now: its ACK must come within half of `period`, the T in force."""
    sent_at: list[float] = []

    def send() -> None:
        sent_at.append(probe.now)
        probe.uplink([occurrence(memory, 0)])

    wait = period / 2 + margin(ctx)
    ack = await probe.answer_to(send, PacketType.ACK, where=acks(memory, 0), wait=wait)
    expected = f"the ACK of {what} at once: within T/2 = {period * 500:g} ms (D-RSP-17)"
    seen_by(ctx, probe, ack, sent_at[-1], sent_at[-1] + period / 2, expected)
