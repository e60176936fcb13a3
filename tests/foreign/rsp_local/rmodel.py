"""The RSP robot model (specs/rsp.md §1) and the binary value format (specs/rcml-2.0.md D-RCML-10).

The XML is read with expat under the profile of specs/xml.md: no DTD is loaded, a document with an
internal subset or any entity declaration is refused before its content is read, references to
undeclared entities are errors, and elements in a namespace are skipped with their content.
"""

from __future__ import annotations

import math
import re
import struct
import xml.parsers.expat as expat
from dataclasses import dataclass, field
from typing import Any

import bugs

MAX_DOCUMENT = 16 * 1024 * 1024
MAX_DEPTH = 256
MAX_DEVICES = 1024
MAX_DATAGRAM = 65_507


class ModelError(Exception):
    """The robot model cannot be used."""


class Malformed(Exception):
    """Bytes that do not follow the format."""


# --- a minimal, safe XML reader -------------------------------------------------------------


@dataclass
class Element:
    tag: str
    attrs: dict[str, str]
    line: int
    children: list[Element] = field(default_factory=list)


def read_xml(data: bytes) -> Element:
    if len(data) > MAX_DOCUMENT:
        raise ModelError("document larger than 16 MiB")
    parser = expat.ParserCreate(namespace_separator=" ")
    parser.SetParamEntityParsing(expat.XML_PARAM_ENTITY_PARSING_NEVER)
    parser.buffer_text = True
    stack: list[Element] = []
    roots: list[Element] = []
    skipping = 0  # depth inside an element of another namespace
    dtd_named = False  # expat then lets an undeclared entity in an attribute vanish silently
    wide = "utf-16-be" if data.startswith(b"\xfe\xff") else None
    wide = "utf-16-le" if data.startswith(b"\xff\xfe") else wide

    def where() -> str:
        return f"line {parser.CurrentLineNumber}"

    def start(name: str, attrs: dict[str, str]) -> None:
        nonlocal skipping
        if len(stack) + skipping >= MAX_DEPTH:
            raise ModelError(f"{where()}: elements nested deeper than {MAX_DEPTH}")
        if skipping or " " in name:
            skipping += 1
            return
        if dtd_named:
            for ref in REFERENCE.findall(_start_tag(data, parser.CurrentByteIndex, wide)):
                if ref not in PREDEFINED and not ref.startswith("#"):
                    raise ModelError(f"{where()}: reference to undeclared entity {ref}")
        own = {k: v for k, v in attrs.items() if " " not in k}
        element = Element(name, own, parser.CurrentLineNumber)
        (stack[-1].children if stack else roots).append(element)
        stack.append(element)

    def end(name: str) -> None:
        nonlocal skipping
        if skipping:
            skipping -= 1
        else:
            stack.pop()

    def text(data: str) -> None:
        if not skipping and stack and data.strip(" \t\r\n"):
            raise ModelError(f"{where()}: character data in <{stack[-1].tag}>")

    def doctype(name: str, sysid: str | None, pubid: str | None, internal: int) -> None:
        nonlocal dtd_named
        dtd_named = sysid is not None or pubid is not None
        if internal:
            raise ModelError(f"{where()}: internal DTD subset refused")

    def entity(*_: Any) -> None:
        raise ModelError(f"{where()}: entity declaration refused")

    def skipped(name: str, is_parameter: int) -> None:
        raise ModelError(f"{where()}: reference to undeclared entity {name}")

    def external(*_: Any) -> int:
        raise ModelError(f"{where()}: external entity refused")

    parser.StartElementHandler = start
    parser.EndElementHandler = end
    parser.CharacterDataHandler = text
    parser.StartDoctypeDeclHandler = doctype
    parser.EntityDeclHandler = entity
    parser.SkippedEntityHandler = skipped
    parser.ExternalEntityRefHandler = external
    try:
        parser.Parse(data, True)
    except expat.ExpatError as exc:
        raise ModelError(f"not well-formed: {exc}") from None
    if not roots:
        raise ModelError("no root element in no namespace")
    return roots[0]


REFERENCE = re.compile(r"&([^;&]*);")
PREDEFINED = ("lt", "gt", "amp", "quot", "apos")


def _start_tag(data: bytes, index: int, wide: str | None) -> str:
    """The raw text of the start tag at byte `index`, up to its '>' outside quotes."""
    size = 4096
    while True:
        text = data[index : index + size].decode(wide or "latin-1", errors="replace")
        quote = ""
        for at, char in enumerate(text):
            if quote:
                quote = "" if char == quote else quote
            elif char in "\"'":
                quote = char
            elif char == ">":
                return text[: at + 1]
        if index + size >= len(data):
            return text
        size *= 2


# --- field types and values ------------------------------------------------------------------

NUMBERS = {
    "bool": "?",
    "int8": "b",
    "uint8": "B",
    "int16": "h",
    "uint16": "H",
    "int32": "i",
    "uint32": "I",
    "int64": "q",
    "uint64": "Q",
    "float32": "f",
    "float64": "d",
}
ALIASES = {"int": "int32", "float": "float32", "double": "float64"}
TEXTS = ("string", "bytes")
INTEGER_TEXT = re.compile(r"[+-]?[0-9]+\Z")
DOUBLE_TEXT = re.compile(r"[+-]?([0-9]+(\.[0-9]*)?|\.[0-9]+)([eE][+-]?[0-9]+)?\Z")
SECONDS_TEXT = re.compile(r"\+?([0-9]+(\.[0-9]*)?|\.[0-9]+)([eE][+-]?[0-9]+)?\Z")
_START = (
    ":A-Z_a-z\u00c0-\u00d6\u00d8-\u00f6\u00f8-\u02ff\u0370-\u037d\u037f-\u1fff\u200c-\u200d"
    "\u2070-\u218f\u2c00-\u2fef\u3001-\ud7ff\uf900-\ufdcf\ufdf0-\ufffd\U00010000-\U000effff"
)
NAME = re.compile(f"[{_START}][{_START}\\-.0-9\u00b7\u0300-\u036f\u203f-\u2040]*\\Z")


@dataclass(frozen=True)
class Field:
    name: str
    type: str
    count: int = 1
    size: int = 0  # string and bytes only
    low: float | int | None = None
    high: float | int | None = None

    def largest(self) -> int:
        if self.type in TEXTS:
            return self.count * (2 + self.size)
        return self.count * struct.calcsize(">" + NUMBERS[self.type])

    def zero(self) -> Any:
        """D-RSP-20's safe value: 0 or the bound nearest 0, false, empty text or bytes."""
        if self.type == "string":
            one: Any = ""
        elif self.type == "bytes":
            one = b""
        elif self.type == "bool":
            one = False
        else:
            one = 0.0 if self.type.startswith("float") else 0
            if self.low is not None and self.low > 0:
                one = self.low
            elif self.high is not None and self.high < 0:
                one = self.high
        return one if self.count == 1 else [one] * self.count

    def encode(self, value: Any, out: bytearray) -> None:
        values = [value] if self.count == 1 else list(value)
        for one in values:
            if self.type == "string":
                raw = one.encode("utf-8")
                out += struct.pack(">H", len(raw)) + raw
            elif self.type == "bytes":
                out += struct.pack(">H", len(one)) + bytes(one)
            else:
                out += struct.pack(">" + NUMBERS[self.type], one)

    def decode(self, buf: bytes, at: int, lenient_bool: bool = False) -> tuple[Any, int]:
        values: list[Any] = []
        for _ in range(self.count):
            if self.type in TEXTS:
                if at + 2 > len(buf):
                    raise Malformed(f"{self.name}: cut short")
                (n,) = struct.unpack_from(">H", buf, at)
                if n > self.size and bugs.on("bad-field-crash"):
                    # the bug: the value goes into a buffer of `size` bytes before the check
                    slot = memoryview(bytearray(self.size))
                    slot[:n] = bytes(buf[at + 2 : at + 2 + n]).ljust(n, b"\0")
                if n > self.size:
                    raise Malformed(f"{self.name}: length {n} above size {self.size}")
                if at + 2 + n > len(buf):
                    raise Malformed(f"{self.name}: cut short")
                raw = buf[at + 2 : at + 2 + n]
                at += 2 + n
                if self.type == "bytes":
                    values.append(raw)
                    continue
                try:
                    values.append(raw.decode("utf-8"))
                except UnicodeDecodeError:
                    raise Malformed(f"{self.name}: not UTF-8") from None
            else:
                code = NUMBERS[self.type]
                width = struct.calcsize(">" + code)
                if at + width > len(buf):
                    raise Malformed(f"{self.name}: cut short")
                if self.type == "bool":
                    byte = buf[at]
                    if bugs.on("bad-field-crash"):
                        values.append((False, True)[byte])  # the bug: the byte as an index
                        at += width
                        continue
                    if byte > 1 and not lenient_bool:
                        raise Malformed(f"{self.name}: bool byte {byte:#04x}")
                    values.append(byte != 0)
                else:
                    values.append(struct.unpack_from(">" + code, buf, at)[0])
                at += width
        return (values[0] if self.count == 1 else values), at


# --- the model -------------------------------------------------------------------------------

KINDS = (
    "module",
    "effector",
    "sensor",
    "monitor",
    "command",
    "event",
    "memoryCommand",
    "memoryEvent",
)
OCCURRENCES = ("command", "event", "memoryCommand", "memoryEvent")
ROOT_ATTRS = {
    "version",
    "name",
    "modelId",
    "idLength",
    "commandBuffers",
    "period",
    "title",
    "author",
}
DEVICE_ATTRS = {"name"}
FIELD_ATTRS = {"name", "type", "count", "size", "min", "max", "unit"}


@dataclass
class Device:
    index: int
    name: str
    kind: str
    fields: list[Field]
    module: str | None = None
    of: str | None = None
    on_loss: str = "hold"

    def largest(self, id_length: int) -> int:
        extra = id_length if self.kind in OCCURRENCES else 0
        return extra + sum(f.largest() for f in self.fields)


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

    def first(self, kind: str) -> Device | None:
        return next((d for d in self.devices if d.kind == kind), None)


def _integer(text: str, low: int, high: int, what: str) -> int:
    if not text.isascii() or not text.isdigit() or not low <= int(text) <= high:
        raise ModelError(f"{what} must be an integer from {low} to {high}, not {text!r}")
    return int(text)


def _bound(text: str | None, ftype: str, what: str) -> float | int | None:
    if text is None:
        return None
    if ftype in ("bool", *TEXTS):
        raise ModelError(f"{what}: min and max only on numbers")
    if ftype.startswith("float"):
        if not DOUBLE_TEXT.match(text):
            raise ModelError(f"{what}: {text!r} is not a finite number")
        value = float(text)
        if ftype == "float32":
            try:
                value = struct.unpack(">f", struct.pack(">f", value))[0]
            except OverflowError:
                raise ModelError(f"{what}: {text!r} overflows float32") from None
        if not math.isfinite(value):
            raise ModelError(f"{what}: {text!r} is not finite")
        return value
    if not INTEGER_TEXT.match(text):
        raise ModelError(f"{what}: {text!r} is not an integer")
    number = int(text)
    try:
        struct.pack(">" + NUMBERS[ftype], number)
    except struct.error:
        raise ModelError(f"{what}: {text!r} is out of {ftype}'s range") from None
    return number


def _check_attrs(el: Element, allowed: set[str], required: tuple[str, ...]) -> None:
    for name in el.attrs:
        if name not in allowed:
            raise ModelError(f"line {el.line}: <{el.tag}> has no attribute {name!r}")
    for name in required:
        if name not in el.attrs:
            raise ModelError(f"line {el.line}: <{el.tag}> needs {name!r}")


def _name(el: Element) -> str:
    name = el.attrs["name"]
    if not NAME.match(name) or len(name.encode("utf-8")) > 255:
        raise ModelError(f"line {el.line}: {name!r} is not an XML Name of at most 255 bytes")
    return name


def _field(el: Element) -> Field:
    _check_attrs(el, FIELD_ATTRS, ("name", "type"))
    for child in el.children:
        _meta(child)
    what = f"line {el.line}: field {el.attrs['name']!r}"
    ftype = ALIASES.get(el.attrs["type"], el.attrs["type"])
    if ftype not in NUMBERS and ftype not in TEXTS:
        raise ModelError(f"{what}: unknown type {el.attrs['type']!r}")
    count = _integer(el.attrs.get("count", "1"), 1, 65535, f"{what}: count")
    size = 0
    if ftype in TEXTS:
        if "size" not in el.attrs:
            raise ModelError(f"{what}: string and bytes need a size")
        size = _integer(el.attrs["size"], 1, 65535, f"{what}: size")
    elif "size" in el.attrs:
        raise ModelError(f"{what}: only string and bytes take a size")
    low = _bound(el.attrs.get("min"), ftype, what)
    high = _bound(el.attrs.get("max"), ftype, what)
    if low is not None and high is not None and low > high:
        raise ModelError(f"{what}: min above max")
    result = Field(_name(el), ftype, count, size, low, high)
    if result.largest() > 1_048_576:
        raise ModelError(f"{what}: larger than 1 MiB")
    return result


def _meta(el: Element) -> None:
    if el.tag != "meta" or el.children:
        raise ModelError(f"line {el.line}: <{el.tag}> is not allowed here")
    _check_attrs(el, {"name", "content"}, ("name", "content"))


def parse_model(data: bytes) -> Model:
    root = read_xml(data)
    if root.tag != "robotModel":
        raise ModelError(f"root element <{root.tag}> is not robotModel")
    _check_attrs(root, ROOT_ATTRS, ("version", "name", "modelId"))
    if root.attrs["version"] != "1":
        raise ModelError("robotModel version must be 1")
    model_id = _integer(root.attrs["modelId"], 1, 65535, "modelId")
    id_length = _integer(root.attrs.get("idLength", "1"), 1, 2, "idLength")
    buffers = _integer(root.attrs.get("commandBuffers", "16"), 1, 127, "commandBuffers")
    period_text = root.attrs.get("period", "0.02")
    if not SECONDS_TEXT.match(period_text) or not 0.005 <= float(period_text) <= 10:
        raise ModelError(f"period {period_text!r} must be 0.005 to 10 seconds")
    devices: list[Device] = []

    def device(el: Element, module: str | None) -> None:
        kind = el.tag
        if kind not in KINDS or (kind == "module" and module is not None):
            raise ModelError(f"line {el.line}: <{kind}> is not allowed here")
        allowed = (
            {"name", "onLoss"}
            if kind == "effector"
            else {"name", "of"}
            if kind == "monitor"
            else {"name"}
        )
        _check_attrs(el, allowed, ("name", "of") if kind == "monitor" else ("name",))
        dev = Device(len(devices), _name(el), kind, [], module)
        devices.append(dev)
        dev.on_loss = el.attrs.get("onLoss", "hold")
        if dev.on_loss not in ("hold", "zero"):
            raise ModelError(f"line {el.line}: onLoss must be hold or zero")
        for child in el.children:
            if kind == "module" and child.tag != "meta":
                device(child, dev.name)
            elif child.tag == "field" and kind not in ("module", "monitor"):
                dev.fields.append(_field(child))
            else:
                _meta(child)
        if kind == "monitor":
            dev.of = el.attrs["of"]
            target = next((d for d in devices if d.name == dev.of), None)
            if target is None or target.kind != "effector":
                raise ModelError(f"line {el.line}: monitor of {dev.of!r}: no effector before it")
            dev.fields = target.fields
        elif kind != "module" and not dev.fields:
            raise ModelError(f"line {el.line}: {kind} {dev.name!r} has no field")
        if len({f.name for f in dev.fields}) != len(dev.fields) and kind != "monitor":
            raise ModelError(f"line {el.line}: field names repeated in {dev.name!r}")

    for child in root.children:
        if child.tag == "meta":
            _meta(child)
        else:
            device(child, None)
    if len({d.name for d in devices}) != len(devices):
        raise ModelError("device names are not distinct")
    if len(devices) > MAX_DEVICES:
        raise ModelError("more than 1,024 devices")
    model = Model(root.attrs["name"], model_id, id_length, buffers, float(period_text), devices)
    down = ("effector", "command", "memoryCommand")
    up = ("sensor", "monitor", "event", "memoryEvent")
    for kinds, direction in ((down, "DOWNLINK"), (up, "UPLINK")):
        total = 20 + model.map_length + 16
        total += sum(d.largest(id_length) for d in devices if d.kind in kinds)
        if total > MAX_DATAGRAM:
            raise ModelError(f"the largest {direction} ({total} bytes) exceeds {MAX_DATAGRAM}")
    return model


def load_model(path: str) -> Model:
    try:
        with open(path, "rb") as f:
            data = f.read(MAX_DOCUMENT + 1)
    except OSError as exc:
        raise ModelError(str(exc)) from None
    return parse_model(data)
