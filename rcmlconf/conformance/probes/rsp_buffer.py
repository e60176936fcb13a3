"""What the cases of the memory-command buffer share (D-RSP-19): memory commands that keep the robot
busy, taking one, and what a count that did not drop says.

Memory commands show whether they were taken by the robot's free-buffer count (the header's buffer
byte): the cases first send one whose `duration` field (if the model has one) keeps the robot
busy, so that those after it wait in the buffer. D-RSP-19 says CUBO's keyframes take their
duration, so a CUBO whose buffer does not fill fails R-RSP-31; another robot may execute memory
commands at once, never fill its buffer, and leave the cases that count on it inconclusive.
"""

from __future__ import annotations

from rcmlconf.conformance.context import Context
from rcmlconf.conformance.probes.rsp_datagram import Datagram
from rcmlconf.conformance.probes.rsp_devices import zero_values
from rcmlconf.conformance.probes.rsp_exchanges import must_ack
from rcmlconf.conformance.probes.rsp_probe import RspProbe
from rcmlconf.conformance.probes.rsp_raw import RawSession
from rcmlconf.conformance.verdicts import CaseStop, Failed, Inconclusive
from rcmlconf.rsp.codec import PacketType
from rcmlconf.rsp.model import Device, DeviceKind
from rcmlconf.values import Value

#: How long the memory commands of a buffer case keep the robot busy (ms, D-RSP-19).
BUSY_MS = 30_000
#: The robot's packets whose header gives its free buffers.
FROM_ROBOT = (PacketType.UPLINK, PacketType.ACK)


def keyframe(found: Device) -> dict[str, Value]:
    """A memory command's fields at their safe values, a duration field (if any) long."""
    values = zero_values(found)
    for field in found.fields:
        if "duration" in field.name.lower() and field.type.base.numeric:
            high = field.maximum if field.maximum is not None else BUSY_MS
            values[field.name] = int(min(high, BUSY_MS))
    return values


def durable(probe: RspProbe, memory: Device) -> bool:
    """Whether the case knows how long `memory`'s commands take: D-RSP-19 says CUBO's motion
    keyframes take their `duration` (R-RSP-44); any other robot's are its own business."""
    return probe.model.name == "CUBO" and any("duration" in f.name.lower() for f in memory.fields)


def not_held(probe: RspProbe, memory: Device, what: str) -> CaseStop:
    """The robot's free buffers did not stay down for memory commands sent while one executes.
    A CUBO with a 30 s keyframe running must hold the next ones (R-RSP-31: its free count says
    so). Any other robot may execute memory commands at once, and the case cannot tell."""
    if durable(probe, memory):
        return Failed(
            "R-RSP-31",
            f"fewer free buffers while {memory.name} keyframes of {BUSY_MS} ms wait (D-RSP-19)",
            what,
        )
    return Inconclusive(f"the robot executes memory commands at once: {what}")


async def take(
    ctx: Context,
    probe: RspProbe,
    raw: RawSession,
    found: Device,
    ident: int,
    *,
    buffer: int = 0,
) -> Datagram:
    """Send memory command or command `ident` (a memory command keeps the robot busy) and
    return the robot's ACK of it, which must come (`must_ack`, R-RSP-26)."""
    values = keyframe(found) if found.kind is DeviceKind.MEMORY_COMMAND else None
    return await must_ack(ctx, probe, raw, found, ident, "R-RSP-26", values=values, buffer=buffer)
