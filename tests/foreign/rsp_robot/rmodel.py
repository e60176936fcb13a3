"""The robot model (specs/rsp.md §1) and the binary value format of its fields (D-RCML-9/10).

A deliberately small reader: pyexpat from the standard library, no DTD loaded, no entity
declared or expanded (D-XML-3, D-XML-4), elements of other namespaces skipped (D-XML-6), at most
16 MiB and 256 levels (D-XML-5). It checks what the robot needs to speak the model's wire format;
`rcmlconf validate` is the full checker.
"""

from __future__ import annotations

import math
import pyexpat
import re
import struct
from dataclasses import dataclass, field
from typing import Any

MAX_DOCUMENT = 16 * 1024 * 1024
MAX_DEPTH = 256

EFFECTOR = "effector"
SENSOR = "sensor"
MONITOR = "monitor"
MODULE = "module"
COMMAND = "command"
EVENT = "event"
MEMORY_COMMAND = "memoryCommand"
MEMORY_EVENT = "memoryEvent"
DEVICE_KINDS = (MODULE, EFFECTOR, SENSOR, MONITOR, COMMAND, EVENT, MEMORY_COMMAND, MEMORY_EVENT)
WITH_FIELDS = (EFFECTOR, SENSOR, COMMAND, EVENT, MEMORY_COMMAND, MEMORY_EVENT)
WITH_ID = (COMMAND, EVENT, MEMORY_COMMAND, MEMORY_EVENT)

ALIASES = {"int": "int32", "float": "float32", "double": "float64"}
# type -> (struct code, family, lowest, highest)
NUMERIC: dict[str, tuple[str, str, float, float]] = {
    "int8": ("b", "int", -(2**7), 2**7 - 1),
    "uint8": ("B", "int", 0, 2**8 - 1),
    "int16": ("h", "int", -(2**15), 2**15 - 1),
    "uint16": ("H", "int", 0, 2**16 - 1),
    "int32": ("i", "int", -(2**31), 2**31 - 1),
    "uint32": ("I", "int", 0, 2**32 - 1),
    "int64": ("q", "int", -(2**63), 2**63 - 1),
    "uint64": ("Q", "int", 0, 2**64 - 1),
    "float32": ("f", "float", -math.inf, math.inf),
    "float64": ("d", "float", -math.inf, math.inf),
}
TYPES = (*NUMERIC, "bool", "string", "bytes")

NAME_RE = re.compile(r"^[A-Za-z_:\u00c0-\U000effff][-.0-9A-Za-z_:\u00b7\u00c0-\U000effff]*$")
SECONDS_RE = re.compile(r"^\+?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?$")
INT_RE = re.compile(r"^[+-]?[0-9]+$")
FLOAT_RE = re.compile(r"^[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?$")


class ModelError(Exception):
    """The model file cannot be used."""


class Malformed(Exception):
    """A payload does not follow the model (R-RCML-30, R-RSP-16)."""


# --- a minimal, safe XML reader ---------------------------------------------------------------


@dataclass
class Element:
    tag: str
    attrs: dict[str, str]
    line: int
    children: list[Element] = field(default_factory=list)


def read_xml(data: bytes) -> Element:
    """Parse a document into its no-namespace elements, refusing DTDs and entities."""
    if len(data) > MAX_DOCUMENT:
        raise ModelError("document larger than 16 MiB")
    parser = pyexpat.ParserCreate(namespace_separator=" ")
    parser.SetParamEntityParsing(pyexpat.XML_PARAM_ENTITY_PARSING_NEVER)
    stack: list[Element] = []
    root: list[Element] = []
    skip = 0  # depth inside an element of another namespace

    def refuse(what: str) -> None:
        raise ModelError(f"line {parser.CurrentLineNumber}: {what}")

    def doctype(_name: str, _sys: str | None, _pub: str | None, internal: int) -> None:
        if internal:
            refuse("an internal DTD subset is not allowed")

    def entity_decl(*_args: Any) -> None:
        refuse("entity declarations are not allowed")

    def skipped_entity(name: str, _is_param: int) -> None:
        refuse(f"entity reference &{name}; is not allowed")

    def external_entity(*_args: Any) -> int:
        refuse("external entities are not loaded")
        return 0

    def start(name: str, attrs: dict[str, str]) -> None:
        nonlocal skip
        if skip or " " in name:
            skip += 1
            return
        if len(stack) >= MAX_DEPTH:
            refuse("elements nest deeper than 256")
        element = Element(name, {k: v for k, v in attrs.items() if " " not in k}, 0)
        element.line = parser.CurrentLineNumber
        if stack:
            stack[-1].children.append(element)
        else:
            root.append(element)
        stack.append(element)

    def end(_name: str) -> None:
        nonlocal skip
        if skip:
            skip -= 1
        else:
            stack.pop()

    def text(data: str) -> None:
        if not skip and stack and data.strip():
            refuse(f"character data in <{stack[-1].tag}>")

    parser.StartDoctypeDeclHandler = doctype
    parser.EntityDeclHandler = entity_decl
    parser.SkippedEntityHandler = skipped_entity
    parser.ExternalEntityRefHandler = external_entity
    parser.StartElementHandler = start
    parser.EndElementHandler = end
    parser.CharacterDataHandler = text
    try:
        parser.Parse(data, True)
    except pyexpat.ExpatError as exc:
        raise ModelError(f"not well-formed XML: {exc}") from None
    if not root:
        raise ModelError("no element")
    return root[0]


# --- the model -----------------------------------------------------------------------------------


@dataclass
class Field:
    name: str
    type: str
    count: int = 1
    size: int = 0
    lo: float | None = None  # min, as the type reads it
    hi: float | None = None
    code: struct.Struct | None = None  # numeric fields: all `count` values at once

    @property
    def numeric(self) -> bool:
        return self.type in NUMERIC

    @property
    def is_float(self) -> bool:
        return self.type in ("float32", "float64")

    def zero_element(self) -> Any:
        """D-RSP-20's safe value: 0, or the bound of the range nearest 0; false; empty."""
        if self.type == "bool":
            return False
        if self.type == "string":
            return ""
        if self.type == "bytes":
            return b""
        zero: float = 0.0 if self.is_float else 0
        if self.lo is not None and zero < self.lo:
            zero = self.lo
        if self.hi is not None and zero > self.hi:
            zero = self.hi
        return zero

    def zero(self) -> tuple[Any, ...]:
        return (self.zero_element(),) * self.count

    def clamp(self, values: tuple[Any, ...]) -> tuple[Any, ...]:
        """Numbers outside min/max are brought to the bound; NaN to the safe value."""
        if not self.numeric or (self.lo is None and self.hi is None):
            return values
        out = []
        for v in values:
            if isinstance(v, float) and math.isnan(v):
                v = self.zero_element()
            elif self.lo is not None and v < self.lo:
                v = self.lo
            elif self.hi is not None and v > self.hi:
                v = self.hi
            out.append(v)
        return tuple(out)


@dataclass
class Device:
    index: int
    kind: str
    name: str
    module: int | None  # index of the module holding it
    fields: list[Field]
    on_loss: str = "hold"
    of: int | None = None  # a monitor's effector

    @property
    def audio(self) -> bool:
        """D-RSP-22: a uint16 fragment number and a bytes field of samples."""
        f = self.fields
        return (
            len(f) == 2
            and f[0].type == "uint16"
            and f[0].count == 1
            and f[1].type == "bytes"
            and f[1].count == 1
        )

    @property
    def all_numeric(self) -> bool:
        return all(f.numeric for f in self.fields)


@dataclass
class Model:
    name: str
    model_id: int
    id_length: int
    command_buffers: int
    period: float
    devices: list[Device]

    @property
    def map_length(self) -> int:
        return (len(self.devices) + 7) // 8

    @property
    def id_space(self) -> int:
        return 1 << (8 * self.id_length)

    def by_name(self, name: str) -> Device:
        for device in self.devices:
            if device.name == name:
                return device
        raise KeyError(name)


def _int(text: str | None, what: str, lo: int, hi: int, default: int) -> int:
    if text is None:
        return default
    if not INT_RE.match(text) or not lo <= int(text) <= hi:
        raise ModelError(f"{what} must be an integer from {lo} to {hi}, not {text!r}")
    return int(text)


def _bound(f: Field, text: str | None) -> float | None:
    if text is None:
        return None
    if not f.numeric:
        raise ModelError(f"field {f.name}: min and max are for numbers only")
    if NUMERIC[f.type][1] == "int":
        if not INT_RE.match(text):
            raise ModelError(f"field {f.name}: bound {text!r} is not an integer")
        value: float = int(text)
        if not NUMERIC[f.type][2] <= value <= NUMERIC[f.type][3]:
            raise ModelError(f"field {f.name}: bound {text!r} outside its type")
        return value
    if not FLOAT_RE.match(text.strip()):
        raise ModelError(f"field {f.name}: bound {text!r} is not a finite number")
    value = float(text)
    if f.type == "float32":
        try:
            value = struct.unpack(">f", struct.pack(">f", value))[0]
        except OverflowError:
            raise ModelError(f"field {f.name}: bound {text!r} overflows float32") from None
    if math.isinf(value):
        raise ModelError(f"field {f.name}: bound {text!r} is not finite")
    return value


def _field(element: Element) -> Field:
    a = element.attrs
    name = a.get("name", "")
    kind = ALIASES.get(a.get("type", ""), a.get("type", ""))
    if not NAME_RE.match(name) or kind not in TYPES:
        raise ModelError(f"line {element.line}: a field needs a name and a known type")
    f = Field(name, kind, _int(a.get("count"), "count", 1, 65535, 1))
    if kind in ("string", "bytes"):
        f.size = _int(a.get("size"), "size", 1, 65535, 0)
        if not f.size:
            raise ModelError(f"field {name}: {kind} needs a size")
    elif "size" in a:
        raise ModelError(f"field {name}: only string and bytes take a size")
    f.lo, f.hi = _bound(f, a.get("min")), _bound(f, a.get("max"))
    if f.lo is not None and f.hi is not None and f.lo > f.hi:
        raise ModelError(f"field {name}: min exceeds max")
    if kind in NUMERIC:
        f.code = struct.Struct(f">{f.count}{NUMERIC[kind][0]}")
    return f


def load_model(data: bytes, on_loss_default: str = "hold") -> Model:
    root = read_xml(data)
    a = root.attrs
    if root.tag != "robotModel" or a.get("version") != "1":
        raise ModelError("the root must be <robotModel version='1'>")
    if not a.get("name"):
        raise ModelError("robotModel needs a name")
    period_text = a.get("period", "0.02")
    if not SECONDS_RE.match(period_text) or not 0.005 <= float(period_text) <= 10:
        raise ModelError(f"period {period_text!r} is not 0.005 to 10 seconds")
    model = Model(
        name=a["name"],
        model_id=_int(a.get("modelId"), "modelId", 1, 65535, 0),
        id_length=_int(a.get("idLength"), "idLength", 1, 2, 1),
        command_buffers=_int(a.get("commandBuffers"), "commandBuffers", 1, 127, 16),
        period=float(period_text),
        devices=[],
    )
    if not model.model_id:
        raise ModelError("robotModel needs a modelId")
    names: set[str] = set()

    def add(element: Element, module: int | None) -> None:
        kind, attrs = element.tag, element.attrs
        name = attrs.get("name", "")
        if not NAME_RE.match(name) or len(name.encode()) > 255 or name in names:
            raise ModelError(f"line {element.line}: device name {name!r} missing or repeated")
        names.add(name)
        device = Device(len(model.devices), kind, name, module, [])
        model.devices.append(device)
        for child in element.children:
            if child.tag == "field" and kind in WITH_FIELDS:
                device.fields.append(_field(child))
            elif child.tag == "meta":
                continue
            elif kind == MODULE and child.tag in DEVICE_KINDS and child.tag != MODULE:
                add(child, device.index)
            else:
                raise ModelError(f"line {child.line}: <{child.tag}> is not allowed in <{kind}>")
        if kind in WITH_FIELDS and not device.fields:
            raise ModelError(f"device {name} has no field")
        if len({f.name for f in device.fields}) != len(device.fields):
            raise ModelError(f"device {name} repeats a field name")
        if kind == EFFECTOR:
            device.on_loss = attrs.get("onLoss", on_loss_default)
            if device.on_loss not in ("hold", "zero"):
                raise ModelError(f"effector {name}: onLoss must be hold or zero")
        if kind == MONITOR:
            target = next((d for d in model.devices if d.name == attrs.get("of")), None)
            if target is None or target.kind != EFFECTOR:
                raise ModelError(f"monitor {name}: of must name an effector before it")
            device.of = target.index
            device.fields = target.fields

    for child in root.children:
        if child.tag in DEVICE_KINDS:
            add(child, None)
        elif child.tag != "meta":
            raise ModelError(f"line {child.line}: <{child.tag}> is not allowed in <robotModel>")
    if len(model.devices) > 1024:
        raise ModelError("more than 1,024 devices")
    return model


# --- the binary value format ---------------------------------------------------------------------


def decode_fields(fields: list[Field], buf: bytes, off: int) -> tuple[tuple[Any, ...], int]:
    """Read one payload's field values from buf at off; each value is a tuple of `count`."""
    values: list[tuple[Any, ...]] = []
    for f in fields:
        if f.code is not None:
            if off + f.code.size > len(buf):
                raise Malformed(f"field {f.name} cut short")
            values.append(f.code.unpack_from(buf, off))
            off += f.code.size
            continue
        elements: list[Any] = []
        for _ in range(f.count):
            if f.type == "bool":
                if off >= len(buf) or buf[off] > 1:
                    raise Malformed(f"field {f.name}: not a bool")
                elements.append(buf[off] == 1)
                off += 1
                continue
            if off + 2 > len(buf):
                raise Malformed(f"field {f.name} cut short")
            n = int.from_bytes(buf[off : off + 2], "big")
            off += 2
            if n > f.size or off + n > len(buf):
                raise Malformed(f"field {f.name}: length {n} above size or cut short")
            raw = bytes(buf[off : off + n])
            off += n
            if f.type == "string":
                try:
                    elements.append(raw.decode("utf-8"))
                except UnicodeDecodeError:
                    raise Malformed(f"field {f.name}: not UTF-8") from None
            else:
                elements.append(raw)
        values.append(tuple(elements))
    return tuple(values), off


def encode_fields(
    fields: list[Field], values: tuple[tuple[Any, ...], ...], little_arrays: bool = False
) -> bytes:
    """Encode one payload; `little_arrays` is the array-little-endian fault (arrays packed
    little-endian)."""
    out = bytearray()
    for f, value in zip(fields, values, strict=True):
        if f.code is not None:
            if NUMERIC[f.type][1] == "int":
                value = tuple(round(v) for v in value)
            code = f.code
            if little_arrays and f.count > 1:
                code = struct.Struct("<" + f.code.format[1:])
            out += code.pack(*value)
            continue
        for element in value:
            if f.type == "bool":
                out.append(1 if element else 0)
                continue
            if f.type == "string":
                raw = element.encode("utf-8")[: f.size].decode("utf-8", "ignore").encode("utf-8")
            else:
                raw = bytes(element)[: f.size]
            out += len(raw).to_bytes(2, "big") + raw
    return bytes(out)


def zero_values(fields: list[Field]) -> tuple[tuple[Any, ...], ...]:
    return tuple(f.zero() for f in fields)


def clamp_values(fields: list[Field], values: tuple[tuple[Any, ...], ...]) -> tuple[Any, ...]:
    return tuple(f.clamp(v) for f, v in zip(fields, values, strict=True))
