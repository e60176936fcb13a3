"""The payloads of a whole packet as one struct, when each of them has a fixed size.

A session sends the same Device Map period after period (D-RSP-18), so `maps` works out once per
map what its payloads are; when none has a `string` or `bytes` field, they are one `struct.Struct`
of *flat values* — each payload's ID, then every item of every field — and a packet is one
`unpack_from` or `pack` and a few checks.

Those checks are compiled: a `FlatLayout` writes the source of one `unpack` and one `pack` function
for its slots, every bound and type test spelled out for each value, and compiles it, as
`collections.namedtuple` and `dataclasses` do. The source holds only what this module writes:
identifiers it makes, integers (offsets, indexes, positions), field names as `repr` literals;
bounds and prebuilt items are passed in its namespace. `FlatLayout.source` keeps it for reading.

Whatever this path doubts it leaves to the slots (`payloads`): a value of another Python type than
the struct code's own (an int for a float field, a bool for an int field), a value outside its
bounds (NaN included), a bool byte other than 0x00 and 0x01, a length that is not the layout's, a
struct that refuses a value. The slots then accept the packet after all or say why not, at which
offset. So the two paths agree on what is valid and what it decodes to, and differ only in speed.
"""

from __future__ import annotations

import struct
from collections.abc import Callable, Sequence
from functools import lru_cache
from types import CodeType
from typing import Any

from rcmlconf.hotpath import make_namedtuple
from rcmlconf.rsp.codec.bodies import Item
from rcmlconf.rsp.codec.payloads import ID_CODES, Slot
from rcmlconf.values import Kind

#: The Python type of an item of each kind, as struct gives it back.
_PYTHON_TYPES: dict[Kind, str] = {Kind.BOOL: "bool", Kind.INTEGER: "int", Kind.FLOAT: "float"}
#: Values unpacked into locals, one by one, up to this many; a longer layout is indexed.
_MAX_LOCALS = 255
#: Array items written out one by one up to this count; a longer array is a slice and a loop.
_MAX_INLINE = 16
#: What a compiled `pack` may raise for items without the layout's shape: the caller then asks the
#: slots, which say what is wrong.
DECLINED = (
    AttributeError,
    IndexError,
    KeyError,
    OverflowError,
    TypeError,
    ValueError,
    struct.error,
)

Unpack = Callable[[Any, int], tuple[Item, ...] | None]
Pack = Callable[[Sequence[Item]], bytes | None]


class _Value:
    """One field (or ID) of one slot in the flat values: what the generated code tests."""

    __slots__ = ("count", "first", "high", "kind", "low", "name", "offset")

    def __init__(
        self,
        name: str | None,
        kind: Kind,
        count: int,
        first: int,
        offset: int,
        low: int | float | None,
        high: int | float | None,
    ) -> None:
        #: The field's name; None for an ID.
        self.name = name
        self.kind = kind
        self.count = count
        #: Index of its first item among the flat values, and byte offset from the payloads.
        self.first = first
        self.offset = offset
        #: Bounds still to test: those the struct code already guarantees are None.
        self.low = low
        self.high = high


class FlatLayout:
    """The payloads of a run of fixed-size slots (`Slot.fixed`), in their order.

    `prefix` (a Device Map) is written before the payloads by `pack`, and not read by `unpack`.
    """

    __slots__ = ("pack", "size", "source", "unpack")

    def __init__(self, slots: Sequence[Slot], id_length: int, prefix: bytes = b"") -> None:
        codes: list[str] = []
        layout: list[tuple[Slot, list[_Value]]] = []
        first = offset = 0
        for slot in slots:
            values: list[_Value] = []
            if slot.has_id:
                codes.append(ID_CODES[id_length])
                values.append(_Value(None, Kind.INTEGER, 1, first, offset, None, None))
                first += 1
                offset += id_length
            for field in slot.fields:
                vtype = field.type
                base = vtype.base
                code = "?" if base.kind is Kind.BOOL else base.code
                codes.append(f"{vtype.count}{code}" if vtype.is_array else code)
                low, high = field.minimum, field.maximum
                if base.kind is Kind.INTEGER:
                    # What the type holds anyway is not tested again.
                    low = None if low is None or low <= base.low else low
                    high = None if high is None or high >= base.high else high
                values.append(_Value(field.name, base.kind, vtype.count, first, offset, low, high))
                first += vtype.count
                offset += vtype.max_encoded_size
            layout.append((slot, values))
        payloads = struct.Struct(">" + "".join(codes))
        whole = struct.Struct(f">{len(prefix)}s" + "".join(codes))
        #: Bytes of the payloads.
        self.size = payloads.size
        namespace: dict[str, Any] = {
            "_unpack_from": payloads.unpack_from,
            "_pack": whole.pack,
            "make_namedtuple": make_namedtuple,
            "Item": Item,
            "_PREFIX": bytes(prefix),
            "_SIZE": payloads.size,
        }
        self.source = _unpack_source(layout, first, namespace) + _pack_source(layout, namespace)
        exec(_compiled(self.source), namespace)
        #: (body, start) -> the items of payloads that fill `body` from `start`; None when the
        #: slots must say.
        self.unpack: Unpack = namespace["unpack"]
        #: items, one to a slot -> the prefix and the payloads; None when the slots must say, or
        #: one of `DECLINED` raised.
        self.pack: Pack = namespace["pack"]


@lru_cache(maxsize=256)
def _compiled(source: str) -> CodeType:
    """The code of a layout's source. Compiling takes most of a layout's making (about a
    millisecond): the codecs of one model (a robot's, its local system's, each session's) share
    it. What differs between layouts of the same source, such as bounds, is in their namespaces.
    """
    return compile(source, "<FlatLayout>", "exec")


def _bound(value: _Value, name: str, namespace: dict[str, Any], item: str) -> str | None:
    """The test that `item` (an expression) is within the value's bounds, or None if unbounded.

    Written as "within" so that NaN, which compares false, is outside.
    """
    if value.low is None and value.high is None:
        return None
    test = item
    if value.low is not None:
        namespace[f"_lo_{name}"] = value.low
        test = f"_lo_{name} <= {test}"
    if value.high is not None:
        namespace[f"_hi_{name}"] = value.high
        test = f"{test} <= _hi_{name}"
    return test


def _unpack_source(
    layout: list[tuple[Slot, list[_Value]]], total: int, namespace: dict[str, Any]
) -> str:
    as_locals = total <= _MAX_LOCALS

    def flat(index: int) -> str:
        return f"v{index}" if as_locals else f"f[{index}]"

    lines = [
        "def unpack(body, start):",
        "    if len(body) - start != _SIZE:",
        "        return None",
    ]
    # R-RCML-30: a bool byte is 0x00 or 0x01; struct's "?" takes any byte as a bool.
    bools = []
    for values in (values for _, values in layout):
        for value in values:
            if value.kind is not Kind.BOOL:
                continue
            if value.count <= _MAX_INLINE:
                bools += [f"body[start + {value.offset + i}] > 1" for i in range(value.count)]
            else:
                window = f"body[start + {value.offset}:start + {value.offset + value.count}]"
                bools.append(f"max({window}) > 1")
    if bools:
        lines += [f"    if {' or '.join(bools)}:", "        return None"]
    lines.append("    f = _unpack_from(body, start)")
    if as_locals and total:
        lines.append(f"    {', '.join(flat(i) for i in range(total))}, = f")
    tests: list[str] = []
    loops: list[str] = []
    for number, (_, values) in enumerate(layout):
        for place, value in enumerate(values):
            name = f"{number}_{place}"
            if value.count <= _MAX_INLINE:
                for i in range(value.count):
                    test = _bound(value, name, namespace, flat(value.first + i))
                    if test is not None:
                        tests.append(test)
            else:
                test = _bound(value, name, namespace, "x")
                if test is not None:
                    end = value.first + value.count
                    loops += [
                        f"    for x in f[{value.first}:{end}]:",
                        f"        if not {test}:",
                        "            return None",
                    ]
    if tests:
        lines += [f"    if not ({' and '.join(tests)}):", "        return None"]
    lines += loops
    items = []
    for number, (slot, values) in enumerate(layout):
        if slot.values is None and not slot.has_id:
            namespace[f"_flag_{number}"] = Item(slot.device)
            items.append(f"_flag_{number}")
            continue
        ident = flat(values[0].first) if slot.has_id else "None"
        fields = values[1:] if slot.has_id else values
        if slot.values is None:
            items.append(f"make_namedtuple(Item, ({slot.device}, {ident}, None))")
            continue
        entries = []
        for value in fields:
            if value.count == 1:
                shown = flat(value.first)
            elif value.count <= _MAX_INLINE:
                shown = "(" + ", ".join(flat(value.first + i) for i in range(value.count)) + ")"
            else:
                shown = f"f[{value.first}:{value.first + value.count}]"
            entries.append(f"{value.name!r}: {shown}")
        items.append(f"make_namedtuple(Item, ({slot.device}, {ident}, {{{', '.join(entries)}}}))")
    lines.append(f"    return ({''.join(item + ', ' for item in items)})")
    return "\n".join(lines) + "\n"


def _pack_source(layout: list[tuple[Slot, list[_Value]]], namespace: dict[str, Any]) -> str:
    lines = ["def pack(items):"]
    # Unpacked even when empty: items of another count are declined (ValueError).
    targets = "".join(f"i{n}, " for n in range(len(layout))) if layout else "[] "
    lines.append(f"    {targets}= items")
    # The devices first: items of another map are declined before any of their values is read,
    # so that `maps` may offer a packet's items to the layout of the map it wrote last.
    devices = [
        f"type(i{number}.device) is int and i{number}.device == {slot.device}"
        for number, (slot, _) in enumerate(layout)
    ]
    if devices:
        lines += [f"    if not ({' and '.join(devices)}):", "        return None"]
    arguments = ["_PREFIX"]
    tests: list[str] = []
    loops: list[str] = []
    for number, (slot, values) in enumerate(layout):
        item = f"i{number}"
        if not slot.has_id:
            tests.append(f"{item}.id is None")
        if slot.values is None:
            tests.append(f"{item}.values is None")
        else:
            lines += [
                f"    d = {item}.values",
                f"    if len(d) != {len(slot.values.names)}:",
                "        return None",
            ]
        for place, value in enumerate(values):
            name = f"{number}_{place}"
            python = _PYTHON_TYPES[value.kind]
            if value.name is None:
                lines.append(f"    a{name} = {item}.id")
            else:
                lines.append(f"    a{name} = d[{value.name!r}]")
            if value.count == 1:
                arguments.append(f"a{name}")
                tests.append(f"type(a{name}) is {python}")
                test = _bound(value, name, namespace, f"a{name}")
                if test is not None:
                    tests.append(test)
                continue
            lines += [
                f"    if type(a{name}) is not tuple and type(a{name}) is not list:",
                "        return None",
            ]
            if value.count <= _MAX_INLINE:
                parts = [f"a{name}_{i}" for i in range(value.count)]
                lines.append(f"    {', '.join(parts)} = a{name}")
                arguments += parts
                for part in parts:
                    tests.append(f"type({part}) is {python}")
                    test = _bound(value, name, namespace, part)
                    if test is not None:
                        tests.append(test)
            else:
                lines += [f"    if len(a{name}) != {value.count}:", "        return None"]
                arguments.append(f"*a{name}")
                test = _bound(value, name, namespace, "x")
                within = f" and {test}" if test is not None else ""
                loops += [
                    f"    for x in a{name}:",
                    f"        if not (type(x) is {python}{within}):",
                    "            return None",
                ]
    if tests:
        lines += [f"    if not ({' and '.join(tests)}):", "        return None"]
    lines += loops
    lines.append(f"    return _pack({', '.join(arguments)})")
    return "\n".join(lines) + "\n"
