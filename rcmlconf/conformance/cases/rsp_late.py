"""rsp/payload: the states of a late DOWNLINK other than effector values (D-RSP-15: "request and
module bits" among them), which a robot must not apply over the newer packet's (R-RSP-19).
rsp/payload/late-state-ignored checks an effector value; a robot that keeps effector values to
newer packets may still take each DOWNLINK's request bits as they come. The harness plays the
local system."""

from __future__ import annotations

from rcmlconf.conformance.context import Context
from rcmlconf.conformance.probes.rsp_datagram import sequence_of
from rcmlconf.conformance.probes.rsp_devices import flags, reported
from rcmlconf.conformance.probes.rsp_exchanges import raw_session, taken, uplinks_within
from rcmlconf.conformance.registry import case
from rcmlconf.conformance.roles import Role
from rcmlconf.conformance.verdicts import Inconclusive

#: Periods the case watches the UPLINKs after the late DOWNLINK: one for the robot to take it,
#: the rest to report what it then holds (an UPLINK every T while a sensor is requested).
WATCH = 4


@case(
    "rsp/payload/late-request-ignored",
    "A late DOWNLINK (not newer) requesting another sensor does not change what the UPLINKs report",
    ["R-RSP-19"],
    role=Role.ROBOT,
)
async def late_request_ignored(ctx: Context) -> None:
    probe, raw = await raw_session(ctx)
    model = probe.model
    asked, other = reported(model, 2)
    raw.skip(5)  # numbers left unused: the late packet's is one never seen (D-RSP-15)
    if await taken(probe, raw, flags(model, asked)) is None:
        raise Inconclusive(f"no UPLINK after the DOWNLINK requesting {asked.name}")
    top = sequence_of(raw.last)
    raw.rewind(top - 3)
    late = raw.downlink(flags(model, other))
    raw.rewind(top + 1)
    uplinks = await uplinks_within(probe, WATCH, raw.period, "the late DOWNLINK")
    wrong = [d for d in uplinks if d.devices(model) != {asked.name}]
    ctx.expect(
        not wrong,
        f"UPLINKs reporting {asked.name} only, as DOWNLINK #{top} (the newest) requests, not"
        f" {other.name} as the late #{sequence_of(late)} does",
        f"{sorted(wrong[0].devices(model))} in UPLINK #{wrong[0].header.sequence}" if wrong else "",
    )
