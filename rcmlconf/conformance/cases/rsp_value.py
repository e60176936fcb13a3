"""rsp/value: what a robot does with a flawed value in a DOWNLINK's payload (specs/rsp.md D-RSP-4,
R-RSP-16, R-RSP-18; specs/rcml-2.0.md D-RCML-12, R-RCML-30). The harness plays the local system.

A payload's fields are values in RCML's binary value format (D-RSP-4). One that does not decode
(R-RCML-30: a bool byte other than 0x00 and 0x01, a length above the field's size, a string that
is not UTF-8, a value cut short, `conformance.flaws`) makes the packet malformed, and a robot
drops a malformed packet without an answer (R-RSP-18): a command in it goes unacknowledged, and
the session goes on. A number outside its field's min and max is another matter: specs/rsp.md
does not say whether it makes the packet malformed or the robot keeps to the range, only that min
and max bound the field (D-RCML-12, D-RSP-4). So the range cases check that much: the effector's
monitor never reports a value outside the range (the probe's codec fails an UPLINK that holds one,
R-RSP-16), whether the robot dropped the value or limited it.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable

from rcmlconf.conformance.context import Context
from rcmlconf.conformance.flaws import Bad, Flaw, flawed, has, spliced
from rcmlconf.conformance.probes.rsp_devices import (
    close_to,
    flags,
    monitored,
    occurrence,
    value_item,
    values_of,
    visible,
    zero_values,
)
from rcmlconf.conformance.probes.rsp_exchanges import going_on, raw_session, unanswered
from rcmlconf.conformance.probes.rsp_probe import RspProbe
from rcmlconf.conformance.probes.rsp_raw import RawSession
from rcmlconf.conformance.registry import case
from rcmlconf.conformance.roles import Role
from rcmlconf.conformance.rsp_numbers import GAP_LONGEST
from rcmlconf.conformance.verdicts import Inconclusive, NotApplicable
from rcmlconf.rsp.codec import Item, MapBody, PacketType
from rcmlconf.rsp.layout import HEADER_SIZE, Bit, MapPacket, bit
from rcmlconf.rsp.model import Device, DeviceKind, Field, RobotModel

#: The ID of the command a case's packets carry, and of the one that shows the session goes on.
_IDENT = 7
#: Periods the range cases send each DOWNLINK for: an effector's value is a state, sent every T
#: (D-RSP-18), and a robot may take a period to move to it (D-RSP-20).
_SETTLE, _EACH = 10, 3


def _model(ctx: Context) -> RobotModel:
    model = ctx.target.rsp_model
    if model is None:
        raise NotApplicable("the RSP robot's model is not known (give --model)")
    return model


def _payload(model: RobotModel, item: Item, flaw: tuple[Field, Bad] | None) -> bytes:
    """One item's payload (D-RSP-14): its ID, its fields in document order (D-RSP-4), the flawed
    field's value replaced by the flawed bytes."""
    device = model.devices[item.device]
    ident = b"" if item.id is None else item.id.to_bytes(model.id_length)
    if item.values is None:
        return ident
    if flaw is None:
        return ident + spliced(device.fields, item.values)
    field, bad = flaw
    return ident + spliced(device.fields, item.values, field, bad.data)


def _with_flaw(
    model: RobotModel, items: Iterable[Item], device: Device, field: Field, bad: Bad
) -> Callable[[bytes], bytes]:
    """A DOWNLINK's alteration: its payloads made again, `device`'s with `bad` as `field`'s
    value. Sessions without encryption only: the body is read as it goes."""
    body = b"".join(
        _payload(model, item, (field, bad) if item.device == device.position else None)
        for item in sorted(items, key=lambda item: item.device)
    )
    return lambda data: data[: HEADER_SIZE + model.map_size] + body


# -- values that do not decode: the packet dropped -------------------------------------------------


def _carrier(model: RobotModel, flaw: Flaw) -> tuple[Device, Field]:
    """A device whose values a DOWNLINK carries (an effector, a command, a memory command) and
    its first field that can have `flaw`."""
    for device in model.devices:
        if bit(device.kind, MapPacket.DOWNLINK) not in (Bit.STATE, Bit.OCCURRENCE):
            continue
        field = next((f for f in device.fields if has(f, flaw)), None)
        if field is not None:
            return device, field
    raise NotApplicable(
        f"{model.name} has no effector, command or memory command with a field {flaw.needs}"
    )


async def _dropped(ctx: Context, flaw: Flaw) -> None:
    """DOWNLINKs carrying a command and a value with `flaw` get no answer (the command is not
    acknowledged, R-RSP-18), and the command in a well-formed one is: the session goes on."""
    model = _model(ctx)
    device, field = _carrier(model, flaw)
    command = next((d for d in model.devices if d.kind is DeviceKind.COMMAND), None)
    if command is None:
        raise NotApplicable(f"{model.name} has no command, whose ACK would show a packet taken")
    values = zero_values(device)
    carried = occurrence(device, _IDENT, values) if device.kind is not DeviceKind.EFFECTOR else None
    items = {command.position: occurrence(command, _IDENT)}
    items[device.position] = carried or value_item(device, values)
    probe, raw = await raw_session(ctx)
    start = probe.mark()
    for bad in flawed(field, flaw):
        raw.send(
            PacketType.DOWNLINK,
            MapBody(tuple(items[p] for p in sorted(items))),
            mutate=_with_flaw(model, items.values(), device, field, bad),
            what=f"DOWNLINK: {command.name}#{_IDENT}, {device.name}/{field.name} = {bad.what}",
        )
    await unanswered(ctx, probe, start, f"DOWNLINKs with {flaw.about}", "R-RSP-18")
    await going_on(ctx, probe, raw, command, _IDENT, "R-RSP-18")


# -- numbers outside the range: never reported ---------------------------------------------------


async def _feed(
    probe: RspProbe,
    raw: RawSession,
    items: list[Item],
    periods: int,
    mutate: Callable[[bytes], bytes] | None = None,
) -> None:
    """A DOWNLINK of `items` every period, `periods` times, as a local system sends states."""
    for _ in range(periods):
        raw.downlink(items, mutate=mutate)
        await probe.listen(raw.period)


async def _within_range(ctx: Context, flaw: Flaw) -> None:
    """An effector is driven to a value its monitor reports, then sent values with `flaw` for a
    few periods each: its monitor goes on reporting, never outside the field's range (the probe
    fails an UPLINK that reports one, R-RSP-16, as its codec reads none)."""
    model = _model(ctx)
    try:
        effector, monitor = monitored(model, lambda e: any(has(f, flaw) for f in e.fields))
    except NotApplicable:
        raise NotApplicable(
            f"{model.name} has no effector of numbers with a monitor and a field {flaw.needs}"
        ) from None
    field = next(f for f in effector.fields if has(f, flaw))
    wanted = {f.name: visible(f) for f in effector.fields}
    request = flags(model, effector, monitor)
    valid = [*request, value_item(effector, wanted)]
    probe, raw = await raw_session(ctx)
    await _feed(probe, raw, valid, _SETTLE)
    latest = probe.packets(PacketType.UPLINK)[-1:]
    reported = values_of(latest[0], monitor) if latest else None
    if reported is None or not close_to(field, reported.get(field.name), wanted[field.name]):
        raise Inconclusive(f"{monitor.name} reported {reported}, not {wanted}: nothing to leave")
    start, began = probe.mark(), probe.now
    for bad in flawed(field, flaw):
        await _feed(probe, raw, valid, _EACH, _with_flaw(model, valid, effector, field, bad))
    await _feed(probe, raw, request, _EACH)  # the value held: what the robot made of them
    uplinks = probe.packets(PacketType.UPLINK, after=start)
    silence = probe.now - began
    # UPLINKs that did not report the monitor are the robot's fault. No UPLINK at all is a
    # silence, which a robot (or a harness) short of CPU keeps too: a timing check, as far past
    # D-RSP-13's longest gap between two UPLINKs as the silence went.
    ctx.expect(
        any(values_of(d, monitor) is not None for d in uplinks),
        f"{monitor.name} reported while its effector was sent {flaw.about}",
        "no report" if uplinks else f"no UPLINK in {silence * 1000:.0f} ms",
        "R-RSP-16",
        timing=not uplinks,
        by=silence - GAP_LONGEST * raw.period,
    )


def _register(flaw: Flaw) -> None:
    if flaw.malformed:

        @case(
            f"rsp/value/{flaw.value}",
            f"A DOWNLINK with {flaw.about} in a payload is dropped unanswered; the session goes on",
            ["R-RSP-18", "R-RCML-30"],
            role=Role.ROBOT,
        )
        async def dropped(ctx: Context) -> None:
            await _dropped(ctx, flaw)

    else:

        @case(
            f"rsp/value/{flaw.value}",
            f"An effector sent {flaw.about} in DOWNLINKs: its monitor never reports a value"
            " outside the range",
            ["R-RSP-16"],
            role=Role.ROBOT,
        )
        async def within_range(ctx: Context) -> None:
            await _within_range(ctx, flaw)


for _flaw in Flaw:
    _register(_flaw)
