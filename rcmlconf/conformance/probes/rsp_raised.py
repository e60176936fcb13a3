"""What an RSP robot under test raises, as a case playing the local system watches for it: a
session by hand whose DOWNLINKs request the devices, beating and acknowledging only when told
(`Beat`, `ack`), and the UPLINKs received, each once in the robot's order
(`received_uplinks`, `watch`).

A robot raises events and memory events when something happens to it, and a case cannot make
anything happen (D-RSP-25): it requests the devices and waits, a bounded time, for what the robot
raises on its own. While it waits, the session is kept alive with a DOWNLINK of its requests every
few periods, and a memory event is acknowledged only when the case says, so that it can watch the
robot send it again.
"""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import Callable, Sequence

from rcmlconf.conformance.context import Context
from rcmlconf.conformance.probes.rsp_datagram import Datagram, sequence_of
from rcmlconf.conformance.probes.rsp_devices import flags, of_kind
from rcmlconf.conformance.probes.rsp_probe import RspProbe, open_probe
from rcmlconf.conformance.probes.rsp_raw import RawSession, hand_driven
from rcmlconf.conformance.verdicts import Inconclusive, NotApplicable
from rcmlconf.rsp.codec import Item, MapBody, PacketType
from rcmlconf.rsp.model import Device, DeviceKind, RobotModel

#: D-RSP-25: how long a case watches for the robot to raise what it needs, seconds (before
#: --timeout-scale).
OCCURS_WITHIN = 2.0
#: D-RSP-13: periods between two packets of a side with nothing new to send.
KEEPALIVE = 5
#: ACK packets sent for one acknowledgement: the robot must have lost them all to send the
#: occurrence again once it has a later packet (a false failure under 20 % loss: 1 in 125).
ACK_COPIES = 3
_SEQUENCE = 1 << 16
_HALF = _SEQUENCE // 2


class Beat:
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


async def requesting(
    ctx: Context, *devices: Device, period_ms: int | None = None
) -> tuple[RspProbe, RawSession]:
    """A session by hand (HELLO asking for `period_ms`, by default the model's) whose DOWNLINKs
    request `devices`, kept alive by a `Beat`."""
    probe = await open_probe(ctx)
    raw = hand_driven(probe, period_ms=period_ms)
    await raw.open()
    raw.standing = flags(probe.model, *devices)
    Beat(ctx, raw)
    return probe, raw


def ack(raw: RawSession, found: Device, ident: int) -> tuple[int, int]:
    """ACK occurrence `ident` of memory event `found`, in ACK_COPIES packets so that a lost one
    does not lose it (an ACK of what is already acknowledged is nothing to its receiver); the
    sequence numbers of the first and the last."""
    sent = [
        sequence_of(raw.send(PacketType.ACK, MapBody((Item(found.position, ident),))))
        for _ in range(ACK_COPIES)
    ]
    return sent[0], sent[-1]


def id_space(model: RobotModel) -> int:
    """How many occurrence IDs there are (D-RSP-5)."""
    return 1 << (8 * model.id_length)


def received_uplinks(probe: RspProbe, after: int) -> list[Datagram]:
    """The UPLINKs received from `after`, each once (a duplicate dropped), in the robot's order
    (by sequence number: a reordered one in its place)."""
    unique: dict[int, Datagram] = {}
    for found in probe.packets(PacketType.UPLINK, after=after):
        unique.setdefault(found.header.sequence, found)
    if not unique:
        return []
    first = next(iter(unique))
    return sorted(unique.values(), key=lambda d: (d.header.sequence - first + _HALF) % _SEQUENCE)


def missing(probe: RspProbe, low: Datagram, high: Datagram) -> bool:
    """Whether a packet the robot numbered between `low` and `high` never arrived: lost, and
    what it carried unknown (so what seems missing from the UPLINKs may have been there)."""
    session = low.header.session_id
    got = {d.header.sequence for d in probe.received if d.header.session_id == session}
    span = (high.header.sequence - low.header.sequence) % _SEQUENCE
    return any((low.header.sequence + k) % _SEQUENCE not in got for k in range(1, span))


async def watch(
    probe: RspProbe, after: int, seconds: float, done: Callable[[list[Datagram]], bool]
) -> list[Datagram]:
    """The UPLINKs received from `after`, once `done` holds of them or `seconds` have passed."""
    deadline = probe.now + seconds
    while True:
        found = received_uplinks(probe, after)
        remaining = deadline - probe.now
        if done(found) or remaining <= 0:
            return found
        await probe.next(after=probe.mark(), wait=remaining)


def nothing_raised(what: str, seconds: float) -> Inconclusive:
    return Inconclusive(f"the robot raised no {what} within {seconds:.2g} s")


def memory_event(model: RobotModel | None) -> Device:
    """The model's first memory event device; NotApplicable when it has none."""
    found = of_kind(model, DeviceKind.MEMORY_EVENT) if model is not None else []
    if not found:
        raise NotApplicable(f"{model.name if model else 'the model'} has no memory event")
    return found[0]


def carrying(found_in: Sequence[Datagram], found: Device) -> list[tuple[Datagram, int]]:
    """The UPLINKs of `found_in` carrying an occurrence of `found`, with its ID."""
    return [
        (uplink, item.id)
        for uplink in found_in
        for item in uplink.items
        if item.device == found.position and item.id is not None
    ]


async def memory_event_raised(
    ctx: Context, *, period_ms: int | None = None
) -> tuple[RspProbe, RawSession, Device, Datagram, int]:
    """A session (`requesting`) requesting the model's first memory event device, and the first
    UPLINK carrying an occurrence of it with its ID; Inconclusive if the robot raised none."""
    found = memory_event(ctx.target.rsp_model)
    probe, raw = await requesting(ctx, found, period_ms=period_ms)
    start = probe.mark()
    seconds = OCCURS_WITHIN * ctx.scale
    found_in = await watch(probe, start, seconds, lambda u: bool(carrying(u, found)))
    carried = carrying(found_in, found)
    if not carried:
        raise nothing_raised(f"{found.name} (memory event)", seconds)
    sent, ident = carried[0]
    return probe, raw, found, sent, ident


def elapsed_ms(earlier: Datagram, later: Datagram) -> int:
    """Milliseconds of the robot's clock between two of its packets (D-RSP-10's timestamp)."""
    return (later.header.timestamp - earlier.header.timestamp) % (1 << 32)
