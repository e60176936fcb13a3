"""Walk a robot model (specs/rsp.md §1): report every broken rule of R-RSP-1 to R-RSP-12 and build
the `RobotModel`.

The element table (`rsp.schema`) covers attributes, lexical forms and placement; this module adds
what a table cannot say: name lengths and duplicates, fields and their types, monitors, the number
of devices and the size of the largest packets. Model order is document order with a module before
its members (D-RSP-2): a device's position in it is its bit in the Device Map.
"""

from __future__ import annotations

from collections.abc import Container
from pathlib import Path

from rcmlconf.markup.document import XmlElement
from rcmlconf.markup.structure import Attributes, Checker, ElementDef
from rcmlconf.rsp.layout import MAX_DATAGRAM, MapPacket, largest_packet
from rcmlconf.rsp.model import (
    DEFAULT_COMMAND_BUFFERS,
    DEFAULT_ID_LENGTH,
    DEFAULT_PERIOD,
    MAX_DEVICES,
    Device,
    DeviceKind,
    Field,
    Meta,
    OnLoss,
    RobotModel,
)
from rcmlconf.rsp.schema import ELEMENTS
from rcmlconf.values.declared import Number, declared_bounds, declared_type
from rcmlconf.wording import shorten

#: D-RSP-2: a device's or field's name, in bytes of UTF-8.
MAX_NAME_BYTES = 255

_ROOT = ELEMENTS["robotModel"]
_FIELD = ELEMENTS["field"]
_META = ELEMENTS["meta"]


def load_model(checker: Checker) -> RobotModel | None:
    """The document's model, or None when the checker recorded any error."""
    return _Walk(checker).model(checker.document.root)


def load(checker: Checker, base_dir: Path | None, resolve: object) -> RobotModel | None:
    """The validator's entry point (`validate.languages`); a model refers to no other document."""
    return load_model(checker)


class _Walk:
    def __init__(self, checker: Checker) -> None:
        self.check = checker
        #: Model order (D-RSP-2).
        self.devices: list[Device] = []
        #: The position of the first device of each name.
        self.positions: dict[str, int] = {}
        #: Monitors to resolve once every device is known: position, element, `of`.
        self.monitors: list[tuple[int, XmlElement, str]] = []

    def model(self, root: XmlElement) -> RobotModel | None:
        attrs = self.check.attributes(root, _ROOT)
        meta = self._members(root, _ROOT, None)
        self._monitors()
        devices = tuple(self.devices)
        if not devices:
            self.check.warning(
                "R-RSP-12", root, "the model has no device: its packets carry nothing"
            )
        id_length = attrs.text("idLength")
        # Built even when invalid, with defaults for what is missing, so that the sizes of
        # R-RSP-11 are checked alongside everything else; it is returned only when valid.
        model = RobotModel(
            name=attrs.text("name") or "",
            model_id=attrs.integer("modelId") or 0,
            devices=devices,
            id_length=int(id_length) if id_length else DEFAULT_ID_LENGTH,
            command_buffers=attrs.integer("commandBuffers") or DEFAULT_COMMAND_BUFFERS,
            period=attrs.number("period") or DEFAULT_PERIOD,
            title=attrs.text("title"),
            author=attrs.text("author"),
            meta=meta,
            by_name={name: devices[position] for name, position in self.positions.items()},
        )
        self._sizes(root, model)
        return None if self.check.error_count else model

    def _members(
        self, element: XmlElement, spec: ElementDef, module: str | None
    ) -> tuple[Meta, ...]:
        """Walk the devices the root or a module holds, in model order; return its metadata."""
        meta: list[Meta] = []
        for child in self.check.children(element, spec):
            if child.tag == "meta":
                self._meta(child, meta)
            else:
                self._device(child, module)
        return tuple(meta)

    def _device(self, element: XmlElement, module: str | None) -> None:
        kind = DeviceKind(element.tag)
        spec = ELEMENTS[element.tag]
        attrs = self.check.attributes(element, spec)
        position = len(self.devices)
        if position == MAX_DEVICES:
            self.check.error(
                "R-RSP-10",
                element,
                f"this is device {position + 1:,}: a model has at most {MAX_DEVICES:,} (D-RSP-7)",
            )
        name = self._name(element, attrs, self.positions, "device of this model")
        if name is not None and name not in self.positions:
            self.positions[name] = position
        on_loss = attrs.text("onLoss")
        device = Device(
            position,
            name or "?",
            kind,
            module=module,
            of=attrs.text("of"),
            on_loss=OnLoss(on_loss) if on_loss else OnLoss.HOLD,
        )
        # The device takes its place before a module's members are walked (D-RSP-2).
        self.devices.append(device)
        if kind is DeviceKind.MODULE:
            device = device._replace(meta=self._members(element, spec, device.name))
        else:
            fields, meta = self._payload(element, spec, kind)
            device = device._replace(fields=fields, meta=meta)
        if device.of is not None:
            self.monitors.append((position, element, device.of))
        self.devices[position] = device

    def _name(
        self, element: XmlElement, attrs: Attributes, taken: Container[str], what: str
    ) -> str | None:
        """A device's or field's name (R-RSP-5), which no other `what` may have (R-RSP-6)."""
        name = attrs.text("name")
        if name is None:  # missing or not a Name: reported with the attribute
            return None
        # A name this short cannot reach the limit in bytes: skip the encoding.
        if len(name) > MAX_NAME_BYTES // 4 and len(name.encode()) > MAX_NAME_BYTES:
            self.check.error(
                "R-RSP-5",
                element,
                f"name is {len(name.encode())} bytes, more than {MAX_NAME_BYTES}",
                "name",
            )
        if name in taken:
            self.check.error(
                "R-RSP-6", element, f"another {what} is named {shorten(name)!r}", "name"
            )
        return name

    def _payload(
        self, element: XmlElement, spec: ElementDef, kind: DeviceKind
    ) -> tuple[tuple[Field, ...], tuple[Meta, ...]]:
        """A device's own fields (D-RSP-4) and its metadata."""
        fields: list[Field] = []
        meta: list[Meta] = []
        names: set[str] = set()
        declared = 0
        for child in self.check.children(element, spec):
            if child.tag == "meta":
                self._meta(child, meta)
                continue
            declared += 1
            field = self._field(child, names)
            if field is not None:
                fields.append(field)
        if kind.has_fields and not declared:
            self.check.error(
                "R-RSP-7",
                element,
                f"<{kind.value}> has no field: its payload would be empty",
                hint='add <field name="..." type="..."/>',
            )
        return tuple(fields), tuple(meta)

    def _field(self, element: XmlElement, names: set[str]) -> Field | None:
        attrs = self.check.attributes(element, _FIELD)
        meta: list[Meta] = []
        for child in self.check.children(element, _FIELD):
            self._meta(child, meta)
        name = self._name(element, attrs, names, "field of this device")
        if name is not None:
            names.add(name)
        vtype, problems = declared_type(
            attrs.text("type"), attrs.integer("count"), attrs.integer("size")
        )
        low: Number | None = None
        high: Number | None = None
        if vtype is not None:
            low, high, more = declared_bounds(vtype, attrs.text("min"), attrs.text("max"))
            problems += more
        for problem in problems:
            # R-RSP-8 adopts R-RCML-18 to R-RCML-21 for fields: findings are reported under it.
            self.check.error("R-RSP-8", element, problem.message, problem.attribute, problem.hint)
        if vtype is None or problems:  # left out, so that R-RSP-11 does not repeat R-RSP-8
            return None
        return Field(name or "?", vtype, low, high, attrs.text("unit"), tuple(meta))

    def _meta(self, element: XmlElement, meta: list[Meta]) -> None:
        attrs = self.check.attributes(element, _META)
        self.check.leaf(element, _META)
        name, content = attrs.text("name"), attrs.text("content")
        if name is not None and content is not None:
            meta.append(Meta(name, content))

    def _monitors(self) -> None:
        """R-RSP-9: a monitor has the fields of the effector before it that `of` names (D-RSP-4)."""
        for position, element, of in self.monitors:
            target = self.positions.get(of)
            watched = None if target is None else self.devices[target]
            if watched is None:
                problem = f"of={shorten(of)!r} names no device of this model"
            elif watched.kind is not DeviceKind.EFFECTOR:
                problem = f"of={of!r} names a <{watched.kind.value}>, not an <effector>"
            elif watched.position > position:
                problem = f"the effector {of!r} comes after this monitor in model order"
            else:
                self.devices[position] = self.devices[position]._replace(fields=watched.fields)
                continue
            self.check.error(
                "R-RSP-9",
                element,
                problem,
                "of",
                "a monitor watches an effector named before it (D-RSP-4)",
            )

    def _sizes(self, root: XmlElement, model: RobotModel) -> None:
        """R-RSP-11: the largest packet of each direction fits in one UDP datagram (D-RSP-7)."""
        for packet in (MapPacket.DOWNLINK, MapPacket.UPLINK):
            size = largest_packet(model, packet)
            if size > MAX_DATAGRAM:
                self.check.error(
                    "R-RSP-11",
                    root,
                    f"the largest {packet.value} is {size:,} bytes (header, Device Map, every "
                    f"payload at its largest, AEAD tag), more than the {MAX_DATAGRAM:,} of one "
                    "UDP datagram",
                    hint="make the largest fields smaller (their size or count)",
                )
