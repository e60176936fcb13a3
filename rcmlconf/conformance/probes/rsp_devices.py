"""The robot model, as RSP cases pick devices from it (`of_kind`, `first`, `monitored`,
`reported`) and make the values and items they send (`zero_values`, `visible`, `flags`,
`occurrence`, `value_item`) or read (`values_of`, `close_to`)."""

from __future__ import annotations

from collections.abc import Callable, Mapping

from rcmlconf.conformance.probes.rsp_datagram import Datagram
from rcmlconf.conformance.verdicts import NotApplicable
from rcmlconf.rsp.codec import Item
from rcmlconf.rsp.model import Device, DeviceKind, Field, RobotModel
from rcmlconf.values import Kind, Value


def of_kind(model: RobotModel, *kinds: DeviceKind) -> list[Device]:
    return [d for d in model.devices if d.kind in kinds]


def numeric(device: Device) -> bool:
    return bool(device.fields) and all(f.type.base.numeric for f in device.fields)


def zero_values(device: Device) -> dict[str, Value]:
    """Every field at D-RSP-20's safe value: a valid payload of any device with fields."""
    return {f.name: f.zero() for f in device.fields}


def visible(field: Field) -> Value:
    """A value of a numeric field well away from 0 and within its range."""
    kind = field.type.base.kind
    high = field.maximum if field.maximum is not None else 1000
    low = field.minimum if field.minimum is not None else -1000
    target = high * 0.4 if high > 0 else low * 0.4
    if low > 0:
        target = low + (high - low) * 0.4
    item: int | float = float(target) if kind is Kind.FLOAT else round(target)
    return tuple([item] * field.type.count) if field.type.is_array else item


def modules_of(model: RobotModel, *found: Device) -> list[Device]:
    """The modules holding `found`, to activate."""
    names = {d.module for d in found if d.module is not None}
    return [d for d in model.devices if d.kind is DeviceKind.MODULE and d.name in names]


def monitored(
    model: RobotModel, where: Callable[[Device], bool] = lambda _: True
) -> tuple[Device, Device]:
    """An effector with all-numeric fields and a monitor of it (`where` holds of the effector);
    NotApplicable when the model has none."""
    for monitor in of_kind(model, DeviceKind.MONITOR):
        effector = model.device(monitor.of or "")
        if effector is not None and numeric(effector) and where(effector):
            return effector, monitor
    raise NotApplicable(f"{model.name} has no numeric effector with a monitor that fits")


def first(model: RobotModel, kind: DeviceKind) -> Device:
    for found in model.devices:
        if found.kind is kind:
            return found
    raise NotApplicable(f"{model.name} has no {kind.value}")


def flags(model: RobotModel, *found: Device) -> list[Item]:
    """DOWNLINK items requesting `found` (sensors, monitors, events) with their modules active
    (an effector among them brings its module only: its value is the case's to give)."""
    wanted = {d.position for d in found if d.kind is not DeviceKind.EFFECTOR}
    wanted |= {m.position for m in modules_of(model, *found)}
    return [Item(position) for position in sorted(wanted)]


def occurrence(found: Device, ident: int, values: Mapping[str, Value] | None = None) -> Item:
    """A command or memory command of ID `ident` (its fields at their safe values by default)."""
    return Item(found.position, ident, dict(values) if values is not None else zero_values(found))


def value_item(found: Device, values: Mapping[str, Value]) -> Item:
    return Item(found.position, None, dict(values))


def close_to(field: Field, actual: Value | None, wanted: Value) -> bool:
    """A numeric value as an effector's monitor reads it: within 1 % of the range (or 1)."""
    if not isinstance(actual, int | float) or not isinstance(wanted, int | float):
        return actual == wanted
    span = (
        field.maximum - field.minimum
        if field.maximum is not None and field.minimum is not None
        else 100
    )
    return abs(actual - wanted) <= max(1.0, span / 100)


def reported(model: RobotModel, count: int = 2) -> list[Device]:
    """`count` sensors or monitors with the smallest payloads, those outside modules first (a
    case requesting them has the fewest bytes and bits to handle); NotApplicable if fewer."""
    found = of_kind(model, DeviceKind.SENSOR, DeviceKind.MONITOR)
    found.sort(key=lambda d: (d.module is not None, sum(f.type.max_encoded_size for f in d.fields)))
    if len(found) < count:
        raise NotApplicable(f"{model.name} has fewer than {count} sensors and monitors")
    return found[:count]


def values_of(found: Datagram, device: Device) -> Mapping[str, Value] | None:
    """The values an UPLINK reports of a sensor or monitor; None if it does not."""
    item = found.item(device.position)
    return item.values if item is not None else None
