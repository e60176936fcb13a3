"""The names a robot model's generated module gives (`generate`, the paper's module creator,
§II.B): XML Names become Python identifiers deterministically. `-`, `.`, `_`, `:` and characters
no identifier may hold separate words, camelCase splits words too; devices and fields become
snake_case (`leftWheel` -> `left_wheel`), classes PascalCase (`irFire` -> `IrFire...`). A name
that is a keyword or that the module needs for itself gets a `_` suffix (`class` -> `class_`); two
devices (or two fields of a device) that become the same identifier are refused (`NameClash`),
since either would hide the other."""

from __future__ import annotations

import keyword
import re
import unicodedata
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

from rcmlconf.errors import RcmlconfError
from rcmlconf.rsp.model import Device, DeviceKind, Field, RobotModel
from rcmlconf.values import Kind


class NameClash(RcmlconfError):
    """Two names of the model become the same Python identifier."""


# -- names ----------------------------------------------------------------------------------------

#: Where camelCase starts a word: `leftWheel`, `IRFire`, `lcd2Left`.
_CAMEL = re.compile(r"(?<=[a-z0-9])(?=[A-Z])|(?<=[A-Z])(?=[A-Z][a-z])")
_UPPER = str.maketrans("abcdefghijklmnopqrstuvwxyz", "ABCDEFGHIJKLMNOPQRSTUVWXYZ")
_LOWER = str.maketrans("ABCDEFGHIJKLMNOPQRSTUVWXYZ", "abcdefghijklmnopqrstuvwxyz")
#: What the generated module uses as types: a field or attribute of that name would hide them.
_TYPES = frozenset({"int", "float", "bool", "str", "bytes", "tuple"})
#: A field is a NamedTuple field (tuple has `count` and `index`) and a keyword argument of a method.
_FIELD_RESERVED = _TYPES | {"self", "count", "index"}
#: A device is an attribute of its module's class, beside `set_active`.
_DEVICE_RESERVED = _TYPES | {"set_active"}
#: Module-level names the generated module imports or defines besides classes.
_TOP_RESERVED = frozenset(
    {
        "Callable",
        "DeviceAccess",
        "Final",
        "LookupError",
        "NamedTuple",
        "TypeError",
        "Value",
        "Values",
    }
)

_KIND_SUFFIX = {
    DeviceKind.MODULE: "Module",
    DeviceKind.EFFECTOR: "Effector",
    DeviceKind.SENSOR: "Sensor",
    DeviceKind.MONITOR: "Monitor",
    DeviceKind.COMMAND: "Command",
    DeviceKind.EVENT: "Event",
    DeviceKind.MEMORY_COMMAND: "MemoryCommand",
    DeviceKind.MEMORY_EVENT: "MemoryEvent",
}


def _keeps(char: str) -> bool:
    """A character an identifier may hold: ASCII letters and digits, and the letters, marks and
    digits of other scripts that Python takes (after NFKC, which Python applies to identifiers)."""
    if char.isascii():
        return char.isalnum()
    return ("a" + unicodedata.normalize("NFKC", char)).isidentifier()


def words(name: str) -> list[str]:
    """An XML Name's words: split at characters identifiers do not keep and at camelCase."""
    chunks = "".join(c if _keeps(c) else " " for c in name).split()
    return [word for chunk in chunks for word in _CAMEL.sub(" ", chunk).split()]


def snake_name(name: str, reserved: Iterable[str] = ()) -> str:
    """`leftWheel` -> `left_wheel`; ASCII letters only change case."""
    text = "_".join(w.translate(_LOWER) for w in words(name)) or "x"
    return _usable(text if text.isidentifier() else "x_" + text, reserved)


def pascal_name(name: str, reserved: Iterable[str] = ()) -> str:
    """`irFire` -> `IrFire`, `IRFire` -> `IrFire`."""
    text = "".join(w[0].translate(_UPPER) + w[1:].translate(_LOWER) for w in words(name)) or "X"
    return _usable(text if text.isidentifier() else "X" + text, reserved)


def _usable(text: str, reserved: Iterable[str]) -> str:
    # Python reads `ﬁ` as `fi` and `e` with a combining acute as `\xe9`: compare what it reads.
    text = unicodedata.normalize("NFKC", text)
    taken = set(reserved)
    while keyword.iskeyword(text) or text in taken:
        text += "_"
    return text


# -- what each device becomes ---------------------------------------------------------------------

_PY_TYPES = {
    Kind.BOOL: "bool",
    Kind.INTEGER: "int",
    Kind.FLOAT: "float",
    Kind.STRING: "str",
    Kind.BYTES: "bytes",
}


@dataclass(frozen=True)
class FieldName:
    field: Field
    #: Its NamedTuple field and keyword argument.
    ident: str

    @property
    def annotation(self) -> str:
        item = _PY_TYPES[self.field.type.base.kind]
        return f"tuple[{item}, ...]" if self.field.type.is_array else item

    @property
    def converter(self) -> str:
        item = _PY_TYPES[self.field.type.base.kind]
        return f"_as_{item}_tuple" if self.field.type.is_array else f"_as_{item}"


@dataclass(frozen=True)
class DeviceNames:
    device: Device
    #: Its attribute in the model's class and its module's.
    attr: str
    #: Its class.
    cls: str
    #: The class of its values, and the function that makes one from a mapping (a monitor's are
    #: its effector's); None for a module.
    values: str | None
    reader: str | None
    fields: tuple[FieldName, ...]


@dataclass(frozen=True)
class ModelNames:
    model_cls: str
    #: What the module's docstring calls the model's object.
    model_var: str
    #: By device name, in model order.
    by_name: dict[str, DeviceNames]

    @property
    def devices(self) -> Iterable[DeviceNames]:
        return self.by_name.values()

    def of(self, name: str) -> DeviceNames:
        return self.by_name[name]


def _clash(what: str, first: str, second: str, ident: str) -> NameClash:
    return NameClash(
        f"{what} {first!r} and {second!r} both become the Python name {ident!r}; rename one"
    )


def _name_fields(device: Device) -> tuple[FieldName, ...]:
    seen: dict[str, str] = {}
    names = []
    for field in device.fields:
        ident = snake_name(field.name, _FIELD_RESERVED)
        if ident in seen:
            raise _clash(f"fields of {device.name!r}:", seen[ident], field.name, ident)
        seen[ident] = field.name
        names.append(FieldName(field, ident))
    return tuple(names)


def _class_names(devices: Sequence[Device]) -> list[str]:
    """`leftWheel` -> `LeftWheelEffector`; a name already ending in its kind keeps one
    (`leftWheelMonitor` -> `LeftWheelMonitor`) unless another device's class has that name."""
    full, short = [], []
    for device in devices:
        suffix = _KIND_SUFFIX[device.kind]
        pascal = pascal_name(device.name)
        full.append(pascal + suffix)
        ends = pascal.endswith(suffix) and pascal != suffix
        short.append(pascal if ends else pascal + suffix)
    chosen = []
    for index, name in enumerate(short):
        others = {*full[:index], *full[index + 1 :], *short[:index], *short[index + 1 :]}
        chosen.append(full[index] if name in others else name)
    return chosen


def model_names(model: RobotModel) -> ModelNames:
    attrs: dict[str, str] = {}
    top: dict[str, str] = {}
    classes = _class_names(model.devices)
    named: list[DeviceNames] = []
    for device, cls in zip(model.devices, classes, strict=True):
        attr = snake_name(device.name, _DEVICE_RESERVED)
        if attr in attrs:
            raise _clash("devices", attrs[attr], device.name, attr)
        attrs[attr] = device.name
        own = [cls]
        values = reader = None
        if device.kind is DeviceKind.MONITOR:
            effector = next(d for d in named if d.device.name == device.of)  # before it (D-RSP-4)
            values, reader = effector.values, effector.reader
        elif device.kind is not DeviceKind.MODULE:
            values = pascal_name(device.name) + "Values"
            reader = f"_{attr}_values"
            own.append(values)
        for ident in own:
            if ident in top:
                raise _clash("devices", top[ident], device.name, ident)
            top[ident] = device.name
        named.append(DeviceNames(device, attr, cls, values, reader, _name_fields(device)))
    short = _first_words(model.name)
    model_cls = pascal_name(short, {*_TOP_RESERVED, *top})
    return ModelNames(model_cls, snake_name(short), {d.device.name: d for d in named})


def _first_words(text: str, limit: int = 40) -> str:
    """The first words of the model's name, which is free text (`CUBO`, `Every kind`), as many
    as make at most `limit` characters (and one at least): its class's name need not be a
    sentence."""
    kept: list[str] = []
    for word in words(text):
        if kept and sum(map(len, kept)) + len(word) > limit:
            break
        kept.append(word)
    return " ".join(kept)
