"""The paper's module creator (§II.B, Fig. 2, Fig. 4): a robot model in, a typed Robot API out.

`generate_module` writes the text of a Python module with one class per device of the model, named
after it (`LeftWheelEffector`, `PositionSensor`, `IrFireCommand`), whose methods are those of the
device's kind, and one class named after the model (`Cubo`) with an attribute per device
(`cubo.left_wheel.write(speed=100)`). The classes only name devices and fields for the application
and convert values; everything else is done by the `rcmlconf.rsp.api.DeviceAccess` they are built
over (the simulacrum), whose codec is generic: nothing per robot runs below this layer.

The text is deterministic (a model and a source name give one text) and ASCII but for identifiers
of other scripts; it is `mypy --strict`- and `ruff check`-clean, and laid out as `ruff format`
lays it out (100 columns) for names of up to 50 characters: `python_text.Writer` splits lines the
way ruff does for the shapes the module has, and a line longer names make too long gets
`# noqa: E501`. The identifiers it gives devices, fields and classes are `generate_names`'.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Sequence

from rcmlconf.rsp.generate_names import DeviceNames, model_names
from rcmlconf.rsp.model import DeviceKind, Field, OnLoss, RobotModel
from rcmlconf.rsp.python_text import (
    LINE_LENGTH,
    STEP,
    Call,
    Writer,
    call,
    escape,
    prose,
    string_literal,
    wrap,
)
from rcmlconf.values import Kind

# -- the module -----------------------------------------------------------------------------------

#: Kinds whose values the application reads back (a monitor reads its effector's).
_READ_BACK = frozenset(
    {DeviceKind.EFFECTOR, DeviceKind.SENSOR, DeviceKind.EVENT, DeviceKind.MEMORY_EVENT}
)
#: Kinds with `listen`, and so `Callable` to import.
_LISTENS = frozenset(
    {DeviceKind.SENSOR, DeviceKind.MONITOR, DeviceKind.EVENT, DeviceKind.MEMORY_EVENT}
)
_KIND_WORDS = {
    DeviceKind.MODULE: "module",
    DeviceKind.EFFECTOR: "effector",
    DeviceKind.SENSOR: "sensor",
    DeviceKind.MONITOR: "monitor",
    DeviceKind.COMMAND: "command",
    DeviceKind.EVENT: "event",
    DeviceKind.MEMORY_COMMAND: "memory command",
    DeviceKind.MEMORY_EVENT: "memory event",
}
#: Python type -> the test that a value the middleware gave back is of it, and the value to return.
_CHECKS = {
    "bool": ("isinstance(value, bool)", "value"),
    "int": ("isinstance(value, int) and not isinstance(value, bool)", "value"),
    "float": ("isinstance(value, int | float) and not isinstance(value, bool)", "float(value)"),
    "str": ("isinstance(value, str)", "value"),
    "bytes": ("isinstance(value, bytes)", "value"),
}


def generate_module(model: RobotModel, source: str) -> str:
    """The text of the Robot API module of `model`; `source` names the model in its header (the
    path it was read from). Raises NameClash when two devices, or two fields of a device, become
    the same Python identifier."""
    return _Module(model, source).text()


def _number(value: int | float) -> str:
    return repr(value)


def _field_doc(field: Field) -> str:
    """`int16, from -500 to 500, in mm/s.` and the field's description, escaped."""
    vtype = field.type
    base = vtype.base.name
    if vtype.base.sized:
        base += f" of at most {vtype.size} bytes"
    parts = [f"an array of {vtype.count} {base}" if vtype.is_array else base]
    each = "each " if vtype.is_array else ""
    if field.minimum is not None and field.maximum is not None:
        parts.append(f"{each}from {_number(field.minimum)} to {_number(field.maximum)}")
    elif field.minimum is not None:
        parts.append(f"{each}at least {_number(field.minimum)}")
    elif field.maximum is not None:
        parts.append(f"{each}at most {_number(field.maximum)}")
    if field.unit:
        parts.append(f"in {prose(field.unit)}")
    text = ", ".join(parts) + "."
    description = _description(field.meta)
    return f"{text} {_sentences(description)}" if description else text


def _example(field: Field) -> str:
    """A value of the field for the module's example: its value nearest 0."""
    kind = field.type.base.kind
    item = {Kind.BOOL: "False", Kind.STRING: "''", Kind.BYTES: "b''"}.get(kind)
    if item is None:
        return repr(field.zero())
    return f"({', '.join([item] * field.type.count)})" if field.type.is_array else item


def _description(meta: Iterable[tuple[str, str]]) -> str:
    return next((prose(content) for name, content in meta if name == "description"), "")


def _sentences(*texts: str) -> str:
    """Texts as sentences: capitalised, each ending in a full stop."""
    return " ".join(t[0].upper() + t[1:] + ("" if t.endswith(".") else ".") for t in texts if t)


class _Module:
    def __init__(self, model: RobotModel, source: str) -> None:
        self.model = model
        self.source = source
        self.names = model_names(model)
        self.out = Writer()
        self.helpers = self._helpers_used()
        #: Effector -> its monitors.
        self.monitors: dict[str, list[str]] = {}
        for device in model.devices:
            if device.of is not None:
                self.monitors.setdefault(device.of, []).append(device.name)

    def text(self) -> str:
        out = self.out
        self._header()
        self._imports()
        out.blank()
        self._model_name()
        out.line(0, f"MODEL_ID: Final = {self.model.model_id}")
        for converter in self.helpers:
            out.blank(2)
            self._helper(converter)
        for names in self.names.devices:
            kind = names.device.kind
            if kind not in (DeviceKind.MODULE, DeviceKind.MONITOR):
                out.blank(2)
                self._values(names)
            if kind in _READ_BACK:
                out.blank(2)
                self._reader(names)
            out.blank(2)
            self._device(names)
        out.blank(2)
        self._model_class()
        return out.text()

    # -- the head of the module

    def _model_name(self) -> None:
        """MODEL_NAME, a string split in parts at spaces when it is too long for a line (ruff
        keeps them apart as long as they would not fit joined)."""
        out = self.out
        literal = string_literal(self.model.name)
        prefix = "MODEL_NAME: Final = "
        if out.fits(0, prefix + literal) or out.fits(STEP, literal):
            out.stmt(0, prefix, literal, parens=True)
            return
        words = re.findall(r"\S*\s*", self.model.name)
        out.line(0, prefix + "(")
        part = ""
        for word in words:
            if part and not out.fits(STEP, string_literal(part + word)):
                out.line(STEP, string_literal(part))
                part = ""
            part += word
        if part:
            out.line(STEP, string_literal(part))
        out.line(0, ")")

    def _header(self) -> None:
        model = self.model
        out = self.out
        out.comment(
            f"Generated by `rcmlconf rsp generate` from {prose(self.source)}: do not edit, "
            "generate it again when the model changes."
        )
        out.comment(
            f"Robot model {prose(model.name)}, model ID {model.model_id}, "
            f"{len(model.devices)} devices (specs/rsp.md section 1)."
        )
        title = f" ({prose(model.title)})" if model.title else ""
        out.doc(
            0,
            f"The Robot API of {prose(model.name)}{title}: a class per device (paper Fig. 4) "
            "over a `rcmlconf.rsp.api.DeviceAccess` such as the simulacrum, which sends and "
            "receives everything. The classes name the devices and fields, and type the values.",
            self._usage(),
        )

    def _usage(self) -> list[str]:
        names = self.names
        var = names.model_var

        def first(*kinds: DeviceKind) -> DeviceNames | None:
            return next((d for d in names.devices if d.device.kind in kinds), None)

        def arguments(device: DeviceNames) -> str:
            return ", ".join(f"{f.ident}={_example(f.field)}" for f in device.fields)

        lines = [f"{var} = {names.model_cls}(access)"]
        effector = first(DeviceKind.EFFECTOR)
        if effector is not None:
            lines.append(f"{var}.{effector.attr}.write({arguments(effector)})")
        sensor = first(DeviceKind.SENSOR, DeviceKind.EVENT)
        if sensor is not None:
            lines.append(f"value = {var}.{sensor.attr}.read(timeout=1.0)")
        command = first(DeviceKind.COMMAND, DeviceKind.MEMORY_COMMAND)
        if command is not None:
            lines.append(f"occurrence = {var}.{command.attr}.issue({arguments(command)})")
        # A line too long to read is left out of the example.
        kept = ["    " + escape(line) for line in lines]
        return ["For example:", ""] + [line for line in kept if len(line) <= 90]

    def _imports(self) -> None:
        out = self.out
        devices = self.names.devices
        out.blank()
        out.line(0, "from __future__ import annotations")
        out.blank()
        if any(d.device.kind in _LISTENS for d in devices):
            out.line(0, "from collections.abc import Callable")
        values = any(d.values is not None for d in devices)
        out.line(
            0, "from typing import Final, NamedTuple" if values else "from typing import Final"
        )
        out.blank()
        reads = any(d.device.kind in _READ_BACK for d in devices)
        out.line(0, f"from rcmlconf.rsp.api import DeviceAccess{', Values' if reads else ''}")
        if self.helpers:
            out.line(0, "from rcmlconf.values import Value")

    # -- what checks the values the middleware gives back

    def _helpers_used(self) -> list[str]:
        used = {
            f.converter for d in self.names.devices if d.device.kind in _READ_BACK for f in d.fields
        }
        order = [name for item in _CHECKS for name in (f"_as_{item}", f"_as_{item}_tuple")]
        # A tuple's helper checks its items with the scalar's.
        return [
            name
            for name in order
            if name in used or (not name.endswith("_tuple") and f"{name}_tuple" in used)
        ]

    def _helper(self, name: str) -> None:
        out = self.out
        item = name.removeprefix("_as_").removesuffix("_tuple")
        if name.endswith("_tuple"):
            out.line(0, f"def {name}(value: Value) -> tuple[{item}, ...]:")
            out.line(4, "if isinstance(value, tuple):")
            out.line(8, f"return tuple(_as_{item}(item) for item in value)")
            out.line(4, f'raise TypeError(f"expected a tuple of {item}, not {{value!r}}")')
            return
        check, result = _CHECKS[item]
        out.line(0, f"def {name}(value: Value) -> {item}:")
        out.line(4, f"if {check}:")
        out.line(8, f"return {result}")
        out.line(4, f'raise TypeError(f"expected {item}, not {{value!r}}")')

    # -- per device

    def _values(self, names: DeviceNames) -> None:
        out = self.out
        device = names.device
        out.line(0, f"class {names.values}(NamedTuple):")
        monitors = self.monitors.get(device.name, [])
        also = f" and of its monitor {_list(monitors)}" if monitors else ""
        out.doc(
            4,
            f"A value of {_KIND_WORDS[device.kind]} {escape(device.name)}{also}: its fields "
            "in model order.",
        )
        out.blank()
        for field in names.fields:
            out.line(4, f"{field.ident}: {field.annotation}")
            out.doc(4, _field_doc(field.field))

    def _reader(self, names: DeviceNames) -> None:
        assert names.values is not None
        assert names.reader is not None
        out = self.out
        out.stmt(
            0,
            "",
            call(f"def {names.reader}(", "values: Values", close=f") -> {names.values}"),
            ":",
        )
        items = tuple(
            (f"{f.ident}=", call(f"{f.converter}(", f"values[{string_literal(f.field.name)}]"))
            for f in names.fields
        )
        out.stmt(4, "return ", Call(f"{names.values}(", items, ")"), parens=True)

    def _device(self, names: DeviceNames) -> None:
        out = self.out
        device = names.device
        out.line(0, f"class {names.cls}:")
        out.doc(4, self._device_doc(names))
        out.blank()
        out.stmt(4, "NAME: Final = ", string_literal(device.name), parens=True)
        out.blank()
        out.line(4, "def __init__(self, access: DeviceAccess) -> None:")
        out.line(8, "self._access = access")
        if device.kind is DeviceKind.MODULE:
            for member in self.model.members(device.name):
                mine = self.names.of(member.name)
                out.stmt(
                    8, f"self.{mine.attr}: Final = ", call(f"{mine.cls}(", "access"), parens=True
                )
        for method in _METHODS[device.kind]:
            out.blank()
            method(self, names)

    def _device_doc(self, names: DeviceNames) -> str:
        device = names.device
        where = f", in module {escape(device.module)}" if device.module else ""
        head = (
            f"{_KIND_WORDS[device.kind].capitalize()} {escape(device.name)}: bit "
            f"{device.position} of the Device Map{where}"
        )
        what = _KIND_DOCS.get(device.kind, "")
        if device.kind is DeviceKind.MODULE:
            members = [m.name for m in self.model.members(device.name)]
            holds = f"it holds {_list(members)}" if members else "it holds no device"
            return _sentences(head, holds, what, _description(device.meta))
        if device.kind is DeviceKind.MONITOR:
            what = f"what effector {escape(device.of or '')} does, as the robot reports it"
        elif device.kind is DeviceKind.EFFECTOR:
            what += (
                " it goes to zero" if device.on_loss is OnLoss.ZERO else " it holds its value"
            ) + " (D-RSP-20)"
        return _sentences(head, what, _description(device.meta))

    # -- methods

    def _signature(self, name: str, *params: str, returns: str) -> None:
        self.out.stmt(4, "", call(f"def {name}(", "self", *params, close=f") -> {returns}"), ":")

    def _keywords(self, names: DeviceNames) -> list[str]:
        return ["*", *(f"{f.ident}: {f.annotation}" for f in names.fields)] if names.fields else []

    def _arguments(self, names: DeviceNames) -> Call:
        return Call(
            "{",
            tuple((f"{string_literal(f.field.name)}: ", f.ident) for f in names.fields),
            "}",
        )

    def _field_lines(self, names: DeviceNames) -> list[str]:
        lines: list[str] = []
        for f in names.fields:
            lines.extend(wrap(f"{f.ident}: {_field_doc(f.field)}", "", "    ", LINE_LENGTH - 8))
        return lines

    def _write(self, names: DeviceNames) -> None:
        self._signature("write", *self._keywords(names), returns="None")
        self.out.doc(
            8,
            "Send this value in every DOWNLINK from now on; it also makes the effector active "
            "(D-RSP-18).",
            self._field_lines(names),
        )
        self.out.stmt(8, "", call("self._access.write(", "self.NAME", self._arguments(names)))

    def _issue(self, names: DeviceNames) -> None:
        self._signature("issue", *self._keywords(names), returns="int")
        memory = names.device.kind is DeviceKind.MEMORY_COMMAND
        how = (
            "sent until acknowledged (D-RSP-17) and then executed in turn from the robot's "
            "command buffers (D-RSP-19)"
            if memory
            else "sent until acknowledged (D-RSP-17)"
        )
        self.out.doc(
            8,
            f"Queue an occurrence, {how}; returns its ID (D-RSP-5).",
            self._field_lines(names),
        )
        self.out.stmt(
            8,
            "return ",
            call("self._access.issue(", "self.NAME", self._arguments(names)),
            parens=True,
        )

    def _read_written(self, names: DeviceNames) -> None:
        assert names.reader is not None
        out = self.out
        self._signature("read", returns=str(names.values))
        out.doc(8, "The value last written (Fig. 4's read); LookupError before the first write.")
        out.line(8, "values = self._access.latest(self.NAME)")
        out.line(8, "if values is None:")
        out.line(12, 'raise LookupError(f"{self.NAME}: nothing written yet")')
        out.stmt(8, "return ", call(f"{names.reader}(", "values"), parens=True)

    def _read_next(self, names: DeviceNames) -> None:
        assert names.reader is not None
        occurrence = names.device.kind.occurrence
        self._signature("read", "timeout: float | None = None", returns=str(names.values))
        wait = (
            "Wait for the next occurrence"
            if occurrence
            else "Wait for a value newer than the one the last `read` gave"
        )
        self.out.doc(8, f"{wait}; TimeoutError after `timeout` seconds (None: no limit).")
        self.out.stmt(
            8,
            "return ",
            call(f"{names.reader}(", call("self._access.read(", "self.NAME", "timeout")),
            parens=True,
        )

    def _latest(self, names: DeviceNames) -> None:
        assert names.reader is not None
        out = self.out
        self._signature("latest", returns=f"{names.values} | None")
        out.doc(8, "The newest value, without waiting; None before any arrived.")
        out.line(8, "values = self._access.latest(self.NAME)")
        out.line(8, "if values is None:")
        out.line(12, "return None")
        out.stmt(8, "return ", call(f"{names.reader}(", "values"), parens=True)

    def _listen(self, names: DeviceNames) -> None:
        assert names.reader is not None
        what = "occurrence" if names.device.kind.occurrence else "new value"
        callback = call("callback: Callable[", f"[{names.values}]", "None", close="]")
        self.out.stmt(
            4,
            "",
            call("def listen(", "self", callback, close=") -> Callable[[], None]"),
            ":",
        )
        self.out.doc(
            8,
            f"Call `callback` with each {what}, from the middleware's thread; returns the "
            "function that stops it.",
        )
        convert = call("callback(", call(f"{names.reader}(", "values"))
        lambda_ = Call(
            "self._access.listen(", (("", "self.NAME"), ("lambda values: ", convert)), ")"
        )
        self.out.stmt(8, "return ", lambda_, parens=True)

    def _set_active(self, names: DeviceNames) -> None:
        self._signature("set_active", "active: bool", returns="None")
        self.out.doc(8, _ACTIVE_DOCS[names.device.kind])
        self.out.line(8, "self._access.set_active(self.NAME, active)")

    # -- the model

    def _model_class(self) -> None:
        out = self.out
        model = self.model
        names = self.names
        out.line(0, f"class {names.model_cls}:")
        title = _sentences(prose(model.title)) if model.title else ""
        out.doc(
            4,
            _sentences(
                f"Robot {prose(model.name)}, model ID {model.model_id}",
                title,
                _description(model.meta),
                "An attribute per device, in model order; a module's devices are its attributes "
                "too",
            ),
        )
        out.blank()
        out.line(4, "def __init__(self, access: DeviceAccess) -> None:")
        for device in names.devices:
            prefix = f"self.{device.attr}: Final = "
            if device.device.module is None:
                out.stmt(8, prefix, call(f"{device.cls}(", "access"), parens=True)
            else:
                module = names.of(device.device.module)
                out.stmt(8, prefix, f"self.{module.attr}.{device.attr}", parens=True)


def _list(items: Sequence[str]) -> str:
    escaped = [escape(i) for i in items]
    return escaped[0] if len(escaped) == 1 else ", ".join(escaped[:-1]) + " and " + escaped[-1]


_KIND_DOCS = {
    DeviceKind.MODULE: "activating or deactivating it does so to all of them (Table I)",
    DeviceKind.EFFECTOR: "its value goes to the robot in every DOWNLINK while it is active; "
    "when the link is lost",
    DeviceKind.SENSOR: "the robot sends its values while it is requested",
    DeviceKind.COMMAND: "each occurrence is sent until the robot acknowledges it",
    DeviceKind.EVENT: "the robot sends an occurrence when its condition is met",
    DeviceKind.MEMORY_COMMAND: "each occurrence waits in the robot's command buffers until it is "
    "executed, in turn",
    DeviceKind.MEMORY_EVENT: "an event the robot sends once, until acknowledged",
}
_ACTIVE_DOCS = {
    DeviceKind.MODULE: "Activate or deactivate the module, and so all its devices (Fig. 4's "
    "setACTIVATED).",
    DeviceKind.EFFECTOR: "Whether its value goes in DOWNLINKs (Fig. 4's setACTIVE).",
    DeviceKind.SENSOR: "Whether to request its values: its bit in the DOWNLINK's Device Map "
    "(D-RSP-14).",
    DeviceKind.MONITOR: "Whether to request its values: its bit in the DOWNLINK's Device Map "
    "(D-RSP-14).",
    DeviceKind.EVENT: "Whether to request its occurrences: its bit in the DOWNLINK's Device Map "
    "(D-RSP-14).",
    DeviceKind.MEMORY_EVENT: "Whether to request its occurrences: its bit in the DOWNLINK's "
    "Device Map (D-RSP-14).",
}
_METHODS = {
    DeviceKind.MODULE: (_Module._set_active,),
    DeviceKind.EFFECTOR: (_Module._write, _Module._read_written, _Module._set_active),
    DeviceKind.SENSOR: (_Module._read_next, _Module._latest, _Module._set_active, _Module._listen),
    DeviceKind.MONITOR: (_Module._read_next, _Module._latest, _Module._set_active, _Module._listen),
    DeviceKind.COMMAND: (_Module._issue,),
    DeviceKind.MEMORY_COMMAND: (_Module._issue,),
    DeviceKind.EVENT: (_Module._read_next, _Module._listen, _Module._set_active),
    DeviceKind.MEMORY_EVENT: (_Module._read_next, _Module._listen, _Module._set_active),
}
