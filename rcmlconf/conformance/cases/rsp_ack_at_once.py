"""rsp/reliable, how soon the robot acknowledges a memory command: at once, within half the period
in force of its arrival (D-RSP-17, R-RSP-26), not with its next UPLINK. The harness plays the local
system. (rsp/reliable/command-acked times the ACKs of commands against the beat of the UPLINKs.)

The session asks for a slow T and requests nothing, so that the robot's packets are its
keep-alives, 5 periods apart (D-RSP-13): a memory command sent right after one of them waits most
of 5 periods for an ACK held for the next packet, and a few milliseconds for one sent at once.
"""

from __future__ import annotations

from rcmlconf.conformance.context import Context
from rcmlconf.conformance.probes.held import margin, seen_by
from rcmlconf.conformance.probes.rsp_devices import first, occurrence, zero_values
from rcmlconf.conformance.probes.rsp_probe import open_probe
from rcmlconf.conformance.probes.rsp_raw import hand_driven
from rcmlconf.conformance.registry import case
from rcmlconf.conformance.roles import Role
from rcmlconf.rsp.codec import PacketType
from rcmlconf.rsp.model import DeviceKind

#: The case asks for a T this long at least (scaled), so that half a period leaves a loaded
#: machine room (as rsp/local/ack-at-once): a robot may raise HELLO's period (D-RSP-13).
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
