"""What a robot's free-buffer count (the header's buffer byte, D-RSP-19) says about the memory
command it is executing and about a late Clear Buffer. The harness plays the local system.

- rsp/reliable/executing-left-buffer: the memory command being executed has left the buffer
  (R-RSP-31). The other buffer cases compare counts with each other, so a robot that counts the
  one it executes (`commandBuffers` - 1 free while one runs alone) passed them all.
- rsp/payload/late-clear-buffer-ignored: the buffer byte is one of a packet's states (D-RSP-15),
  so a late DOWNLINK's Clear Buffer is not applied (R-RSP-19); rsp/payload/late-state-ignored and
  late-request-ignored check the other states.
"""

from __future__ import annotations

from rcmlconf.conformance.context import Context
from rcmlconf.conformance.probes.held import margin, seen_by
from rcmlconf.conformance.probes.rsp_buffer import durable, keyframe, not_held, take
from rcmlconf.conformance.probes.rsp_datagram import Datagram, newer, sequence_of
from rcmlconf.conformance.probes.rsp_devices import first, flags, reported
from rcmlconf.conformance.probes.rsp_exchanges import late_acked, raw_session, taken
from rcmlconf.conformance.probes.rsp_probe import RspProbe, open_probe
from rcmlconf.conformance.probes.rsp_raw import RawSession, hand_driven
from rcmlconf.conformance.registry import case
from rcmlconf.conformance.roles import Role
from rcmlconf.conformance.verdicts import Failed, Inconclusive
from rcmlconf.rsp.codec import CLEAR_BUFFER, PacketType
from rcmlconf.rsp.model import DeviceKind

#: R-RSP-31: a memory command taken while the robot executes none has left the buffer within
#: this many periods T.
START_PERIODS = 3
#: executing-left-buffer asks for a T this long at least (scaled), so that R-RSP-31's three
#: periods leave a loaded machine room: a robot may raise HELLO's period (D-RSP-13).
SLOW_PERIOD = 0.3
#: Memory commands late-clear-buffer-ignored leaves waiting behind the one executing: a Clear
#: Buffer frees them all at once, more than one command done in the meantime could.
WAITING = 2
#: Periods late-clear-buffer-ignored watches the UPLINKs after the late DOWNLINK (one for the
#: robot to read it, the rest to report what it then holds).
WATCH = 4
_STAMPS = 1 << 32
_FROM_ROBOT = (PacketType.UPLINK, PacketType.ACK)


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
        _FROM_ROBOT,
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
    counts = [d.header.buffer for d in probe.packets(_FROM_ROBOT, after=mark) if within(d)]
    if buffers in counts:
        raise not_held(probe, memory, f"#1 taken behind #0, {counts} free within {horizon} ms")
    ctx.expect(
        all(count == buffers - 1 for count in counts),
        f"{buffers - 1} free while #0 executes and #1 waits behind it (D-RSP-19: one executing,"
        " one buffer taken)",
        f"{counts} free",
        "R-RSP-31",
    )


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
    counts = [d.header.buffer for d in probe.packets(_FROM_ROBOT, after=mark)]
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
