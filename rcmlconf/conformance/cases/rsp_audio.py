"""rsp/audio: the robot's audio processor (D-RSP-22).

It plays a speaker's fragments in order and drops a late one (R-RSP-39). A monitor of the
speaker shows what it played (D-RSP-23, R-RSP-40). A model without such a monitor, as CUBO,
leaves these cases not applicable. The harness plays the local system.
"""

from __future__ import annotations

from rcmlconf.conformance.context import Context
from rcmlconf.conformance.probes.rsp_datagram import sequence_of
from rcmlconf.conformance.probes.rsp_devices import (
    of_kind,
    value_item,
    values_of,
    zero_values,
)
from rcmlconf.conformance.probes.rsp_exchanges import fresh_uplink, taken
from rcmlconf.conformance.probes.rsp_probe import RspProbe
from rcmlconf.conformance.probes.rsp_raised import (
    requesting,
)
from rcmlconf.conformance.probes.rsp_raw import RawSession
from rcmlconf.conformance.registry import case
from rcmlconf.conformance.roles import Role
from rcmlconf.conformance.verdicts import Inconclusive, NotApplicable
from rcmlconf.rsp.codec import PacketType
from rcmlconf.rsp.model import Device, DeviceKind, RobotModel
from rcmlconf.values import Kind, Value


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
    probe, raw = await requesting(ctx, monitor, effector)
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
