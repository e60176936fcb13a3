"""rsp/map: the Device Map of D-RSP-14, the robot's side. The harness plays the local system.

- UPLINKs report only the sensors the newest DOWNLINK requested (R-RSP-23).
- A sensor of an inactive module is not reported until the module is activated (R-RSP-23).
- A DOWNLINK with a bit set past the last device is dropped (R-RSP-17, R-RSP-18).
"""

from __future__ import annotations

from rcmlconf.conformance.context import Context
from rcmlconf.conformance.probes.rsp_datagram import (
    newer,
    sequence_of,
)
from rcmlconf.conformance.probes.rsp_devices import (
    flags,
    modules_of,
    of_kind,
    reported,
)
from rcmlconf.conformance.probes.rsp_exchanges import (
    dropped_then_taken,
    must_take,
    raw_session,
    taken,
)
from rcmlconf.conformance.probes.rsp_forged import flip
from rcmlconf.conformance.registry import case
from rcmlconf.conformance.roles import Role
from rcmlconf.conformance.verdicts import Inconclusive, NotApplicable
from rcmlconf.rsp.codec import (
    Item,
    PacketType,
)
from rcmlconf.rsp.model import DeviceKind


@case(
    "rsp/map/only-requested",
    "UPLINKs report only the sensors the newest DOWNLINK requested, and nothing once none are",
    ["R-RSP-23"],
    role=Role.ROBOT,
)
async def only_requested(ctx: Context) -> None:
    probe, raw = await raw_session(ctx)
    model = probe.model
    one, two = reported(model, 2)
    for wanted in ([one], [two], [one, two], []):
        found = await taken(
            probe, raw, flags(model, *wanted), wait=max(probe.quiet, 6 * raw.period)
        )
        sent = sequence_of(raw.last)
        names = {d.name for d in wanted}
        if found is None:
            raise Inconclusive(f"no UPLINK after DOWNLINK {sent}")
        await probe.listen(2 * raw.period)
        for later in probe.packets(PacketType.UPLINK):
            if newer(later.header.last_received, sent):
                ctx.expect(
                    later.devices(model) == names,
                    str(sorted(names)) if names else "an empty Device Map",
                    f"{sorted(later.devices(model))} in UPLINK #{later.header.sequence}",
                )


@case(
    "rsp/map/module-gates-reports",
    "A requested sensor or monitor of an inactive module is not reported until it is activated",
    ["R-RSP-23"],
    role=Role.ROBOT,
)
async def module_gates_reports(ctx: Context) -> None:
    model = ctx.target.rsp_model
    held = (
        [d for d in of_kind(model, DeviceKind.SENSOR, DeviceKind.MONITOR) if d.module is not None]
        if model is not None
        else []
    )
    if not held:
        raise NotApplicable("no sensor or monitor in a module")
    probe, raw = await raw_session(ctx)
    device = held[0]
    module = modules_of(probe.model, device)[0]
    inactive = f"nothing of {device.name} while {module.name} is inactive"
    active = f"{device.name} once {module.name} is active"
    for request, reports, what in (
        ([Item(device.position)], set(), inactive),
        (flags(probe.model, device), {device.name}, active),
    ):
        found = await must_take(ctx, probe, raw, request, f"an UPLINK reporting {what}")
        got = found.devices(probe.model)
        ctx.expect(got == reports, what, str(sorted(got)))


@case(
    "rsp/map/bit-past-last-device",
    "A DOWNLINK with a Device Map bit set past the last device is dropped unanswered",
    ["R-RSP-17", "R-RSP-18"],
    role=Role.ROBOT,
)
async def bit_past_last_device(ctx: Context) -> None:
    model = ctx.target.rsp_model
    if model is None or len(model.devices) % 8 == 0:
        raise NotApplicable("the Device Map has no bit past the last device")
    probe, raw = await raw_session(ctx)
    spare = len(model.devices)
    at = 20 + spare // 8
    await dropped_then_taken(
        ctx, probe, raw, lambda d: flip(d, at, 0x80 >> spare % 8), "R-RSP-17", f"bit {spare} set"
    )
