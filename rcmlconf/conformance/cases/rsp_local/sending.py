"""rsp/local, sending reliably: how an RSP local system under test sends its commands and memory
commands (D-RSP-17): a command in every DOWNLINK until its ACK (R-RSP-27), a memory command again
after each retransmission timeout and not sooner (R-RSP-28), a device's next occurrence only once
the one before is acknowledged (R-RSP-29), numbered 0, 1, 2, ... (R-RSP-24), and no memory command
while the robot has no free buffer (R-RSP-32). The harness plays the robot (`--role local`)."""

from __future__ import annotations

import itertools

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
from rcmlconf.conformance.probes.pace import ms
from rcmlconf.conformance.probes.rsp_devices import first, of_kind
from rcmlconf.conformance.rsp_numbers import (
    MAX_RTO,
    STAMP_ROUNDING,
    resent_within,
    unheard_for,
    unmeasured_rto,
)
from rcmlconf.conformance.verdicts import Inconclusive
from rcmlconf.rsp.codec import PacketType
from rcmlconf.rsp.model import DeviceKind

#: Retransmissions rsp/local/memory-command-resent times at least: the first at 10 T, the second
#: at 20 T (or 2 s).
RESENDS = 2


def _timeouts(period: float) -> list[float]:
    """The unmeasured timeouts (D-RSP-17) rsp/local/memory-command-resent waits out: RESENDS at
    least, and on until one whose doubling the 2 s ceiling cut, so that a timeout doubled past
    2 s shows as a retransmission late."""
    timeouts = [unmeasured_rto(period, 0)]
    while len(timeouts) < RESENDS or 2 * timeouts[-2] <= MAX_RTO:
        timeouts.append(unmeasured_rto(period, len(timeouts)))
    return timeouts


@local_case(
    "rsp/local/command-until-acked",
    "An unacknowledged command rides every DOWNLINK, with its ID, until its ACK; then it stops",
    ["R-RSP-27", "R-RSP-24"],
)
async def command_until_acked(ctx: Context) -> None:
    command = first(played_model(ctx), DeviceKind.COMMAND)
    probe = await session(ctx, withheld=[command], used=False)
    period = probe.period
    carrying = await probe.next(PacketType.DOWNLINK, after=0, where=carries(command))
    if carrying is None:
        raise Inconclusive(f"no {command.name} command issued (D-RSP-24 step 2)")
    item = carrying.item(command.position)
    assert item is not None
    assert item.id is not None
    ident = item.id
    await probe.listen(6 * period)
    riding = probe.packets(PacketType.DOWNLINK, after=probe.after(carrying))
    ctx.expect(
        len(riding) >= 3,
        f"a DOWNLINK every period carrying {command.name} #{ident}",
        f"{len(riding)} DOWNLINKs in {6 * period * 1000:g} ms",
        timing=True,
    )
    for down in riding:
        again = down.item(command.position)
        ctx.expect(
            again is not None,
            f"{command.name} #{ident} in every DOWNLINK until its ACK",
            f"DOWNLINK #{down.header.sequence} without it",
        )
        assert again is not None
        ctx.expect(
            again.id == ident and again.values == item.values,
            f"{command.name} repeated as #{ident} with its values",
            f"#{again.id} {dict(again.values or {})} in DOWNLINK #{down.header.sequence}",
            "R-RSP-24",
        )
    ack = probe.ack([item])
    ack_at = probe.now
    # D-RSP-26: sent after the ACK was had, as bye-ends and the -dropped cases judge it.
    seen = await probe.received_within(
        unheard_for(period, ctx.scale) + 4 * period, PacketType.DOWNLINK
    )
    heard = sent_after(ctx, probe, ack, ack_at)
    after = [d for d in seen if heard(d)]
    if not after:
        raise Inconclusive("no DOWNLINK after the ACK")
    still = [d for d in after if carries(command, ident)(d)]
    ctx.expect(
        not still,
        f"{command.name} #{ident} no more once its ACK arrived",
        f"in DOWNLINK #{still[0].header.sequence}" if still else "",
    )


@local_case(
    "rsp/local/memory-command-resent",
    "An unacknowledged memory command is sent again after each retransmission timeout, no sooner",
    ["R-RSP-28", "R-RSP-29"],
    timeout=12.0,
)
async def memory_command_resent(ctx: Context) -> None:
    model = played_model(ctx)
    memory = first(model, DeviceKind.MEMORY_COMMAND)
    # No command or memory command is acknowledged, so the local system measures no round trip
    # (D-RSP-17 takes them from acknowledged occurrences only): its timeout is 10 T and doubles
    # at each retransmission. An ACK of the scenario's command would give it a measurement that
    # RFC 6298 lets lower the timeout between two retransmissions, and the doubling checked
    # below would not be required.
    reliable = (DeviceKind.COMMAND, DeviceKind.MEMORY_COMMAND)
    withheld = [d for d in model.devices if d.kind in reliable]
    probe = await session(ctx, withheld=withheld, used=False)
    period = probe.period
    sent = await probe.next(PacketType.DOWNLINK, after=0, where=carries(memory))
    if sent is None:
        raise Inconclusive(f"no {memory.name} memory command issued (D-RSP-24 step 2)")
    # Nothing acknowledged, nothing measured: 10 T, then doubled (D-RSP-17), each from the send
    # before; seen within D-RSP-26's bound, read off the harness's clock (`seen_by`).
    timeouts = _timeouts(period)
    sends = [sent]
    for rto in timeouts:
        within = resent_within(rto, period, ctx.scale)
        found = await probe.next(
            PacketType.DOWNLINK,
            after=probe.after(sends[-1]),
            wait=sends[-1].at + within + margin(ctx) - probe.now,
            where=carries(memory),
        )
        seen = ids(probe.packets(PacketType.DOWNLINK), memory)
        ctx.expect(
            len(seen) == 1,
            f"no {memory.name} but #{seen[0]} before its ACK",
            f"#{', #'.join(map(str, seen))}",
            "R-RSP-29",
        )
        expected = (
            f"{memory.name} #{seen[0]} sent again {rto * 1000:.0f} ms after send {len(sends)}"
            f" (D-RSP-17's timeout, doubled but at most 2 s; D-RSP-26: within"
            f" {within * 1000:.0f} ms)"
        )
        last = sends[-1].at
        sends.append(seen_by(ctx, probe, found, last, last + within, expected))
    # "Not sooner", by the local system's own stamps (D-RSP-26: a harness held up reads late).
    stamped = [
        (b.header.timestamp - a.header.timestamp) % (1 << 32) for a, b in itertools.pairwise(sends)
    ]
    ctx.expect(
        all(gap >= rto * 1000 - STAMP_ROUNDING for gap, rto in zip(stamped, timeouts, strict=True)),
        f"no sooner than each retransmission timeout: {ms(timeouts)} (10 T before a round trip"
        " is measured, doubled after each, at most 2 s)",
        f"sent again {', '.join(map(str, stamped))} ms after, by its stamps",
    )


@local_case(
    "rsp/local/next-waits-for-ack",
    "A device's next command or memory command waits for the ACK of the one before",
    ["R-RSP-29"],
)
async def next_waits_for_ack(ctx: Context) -> None:
    model = played_model(ctx)
    command = first(model, DeviceKind.COMMAND)
    memory = first(model, DeviceKind.MEMORY_COMMAND)
    event = first(model, DeviceKind.EVENT)
    probe = await session(ctx, withheld=[command, memory])
    period = probe.period
    both = await probe.next(
        PacketType.DOWNLINK,
        after=0,
        where=lambda d: carries(command)(d) and carries(memory)(d),
    )
    if both is None:
        raise Inconclusive(f"no {command.name} and {memory.name} under way (D-RSP-24 step 2)")
    probe.uplink([occurrence(event, 0)])  # taken, it issues another command (step 3)
    await probe.listen(8 * period)
    downlinks = probe.packets(PacketType.DOWNLINK)
    for device in (command, memory):
        seen = ids(downlinks, device)
        ctx.expect(
            len(seen) == 1,
            f"{device.name} #{seen[0]} alone until its ACK",
            numbered(device, seen),
        )


@local_case(
    "rsp/local/occurrence-ids",
    "The local system numbers each device's occurrences 0, 1, 2, ...: commands and memory commands",
    # R-RSP-16: an ID is read as D-RSP-11 writes it (network byte order); one written the other
    # way round reads #0, #256, ...
    ["R-RSP-24", "R-RSP-16"],
)
async def occurrence_ids(ctx: Context) -> None:
    model = played_model(ctx)
    command = first(model, DeviceKind.COMMAND)
    memory = first(model, DeviceKind.MEMORY_COMMAND)
    events = of_kind(model, DeviceKind.EVENT)
    probe = await session(ctx)
    period = probe.period
    if events:  # each taken, each issues a command (D-RSP-24 step 3)
        probe.uplink([occurrence(events[0], 0)])
        probe.uplink([occurrence(events[0], 1)])
    await probe.next(
        PacketType.DOWNLINK,
        after=0,
        wait=max(12 * period, probe.quiet),
        where=lambda _: len(ids(probe.packets(PacketType.DOWNLINK), memory)) >= 4,
    )
    downlinks = probe.packets(PacketType.DOWNLINK)
    memories, commands = ids(downlinks, memory), ids(downlinks, command)
    if len(memories) < 2:
        raise Inconclusive(f"{memory.name} memory commands are not under way (D-RSP-24 step 2)")
    for device, seen in ((memory, memories), (command, commands)):
        ctx.expect(
            seen == list(range(len(seen))),
            f"{device.name} #0, #1, #2, ...",
            numbered(device, seen),
        )


@local_case(
    "rsp/local/no-free-buffer",
    "No memory command while the robot has no free buffer; one when one frees; none after it",
    ["R-RSP-32"],
)
async def no_free_buffer(ctx: Context) -> None:
    memory = first(played_model(ctx), DeviceKind.MEMORY_COMMAND)
    probe = await session(ctx, free=0, withheld=[memory])
    period = probe.period
    await probe.listen(8 * period)
    if not probe.packets(PacketType.DOWNLINK):
        # D-RSP-13: one every T; a local system that sent none sent no memory command either,
        # which shows nothing of R-RSP-32.
        raise Inconclusive(f"no DOWNLINK in {8 * period:.2f} s: nothing it withheld to see")
    early = [d for d in probe.packets(PacketType.DOWNLINK) if carries(memory)(d)]
    ctx.expect(
        not early,
        f"no {memory.name} while every packet of the robot gives 0 free buffers",
        f"{memory.name} in DOWNLINK #{early[0].header.sequence}" if early else "",
    )
    mark = probe.mark()
    probe.free = 1
    probe.uplink()
    sent = await probe.next(PacketType.DOWNLINK, after=mark, where=carries(memory))
    if sent is None:
        raise Inconclusive(f"no {memory.name} sent when a buffer freed (D-RSP-24 step 2)")
    item = sent.item(memory.position)
    assert item is not None
    probe.free = 0  # the robot took it: full again, and says so before it acknowledges it
    probe.uplink()
    probe.ack([item])
    later = await probe.received_within(8 * period, PacketType.DOWNLINK)
    if not later:
        raise Inconclusive(f"no DOWNLINK in {8 * period:.2f} s after the ACK")
    more = [i for i in ids(later, memory) if i != item.id]
    ctx.expect(
        not more,
        f"no {memory.name} after #{item.id} filled the one free buffer",
        numbered(memory, more),
    )
