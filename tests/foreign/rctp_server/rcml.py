"""RCML 2.0 reading (specs/rcml-2.0.md, specs/xml.md) and the binary value format (D-RCML-10).

The XML is read with expat from the standard library, under the profile of specs/xml.md: no DTD
is loaded, a document with an internal subset or any entity declaration is refused, an entity
reference other than the five predefined ones is refused, elements in other namespaces are
skipped with their content.
"""

from __future__ import annotations

import math
import re
import struct
from collections.abc import Collection
from dataclasses import dataclass, field
from typing import Any
from xml.parsers import expat

MAX_DOCUMENT = 16 * 1024 * 1024
MAX_DEPTH = 256


class RcmlError(Exception):
    """The document is not an RCML 2.0 document this server can serve."""


class Malformed(ValueError):
    """A value that does not decode (R-RCML-30) or lies outside its node's range."""


# type -> (struct code or None, encoded size, lowest, highest); strings and bytes have no code
_INTS = {
    "int8": ("b", 1, -(2**7), 2**7 - 1),
    "uint8": ("B", 1, 0, 2**8 - 1),
    "int16": ("h", 2, -(2**15), 2**15 - 1),
    "uint16": ("H", 2, 0, 2**16 - 1),
    "int32": ("i", 4, -(2**31), 2**31 - 1),
    "uint32": ("I", 4, 0, 2**32 - 1),
    "int64": ("q", 8, -(2**63), 2**63 - 1),
    "uint64": ("Q", 8, 0, 2**64 - 1),
}
_FLOATS = {"float32": ("f", 4), "float64": ("d", 8)}
ALIASES = {"int": "int32", "float": "float32", "double": "float64"}
TYPES = set(_INTS) | set(_FLOATS) | {"bool", "string", "bytes"}

_SECONDS = re.compile(r"\+?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")
_INTEGER = re.compile(r"[+-]?[0-9]+")
_DOUBLE = re.compile(r"[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")

# XML 1.0 fifth edition, production [4] and [4a]
_NAME_START = (
    ":A-Z_a-z\u00c0-\u00d6\u00d8-\u00f6\u00f8-\u02ff\u0370-\u037d\u037f-\u1fff\u200c-\u200d"
    "\u2070-\u218f\u2c00-\u2fef\u3001-\ud7ff\uf900-\ufdcf\ufdf0-\ufffd\U00010000-\U000effff"
)
_NAME_RE = re.compile(f"[{_NAME_START}][{_NAME_START}\\-.0-9\u00b7\u0300-\u036f\u203f-\u2040]*")


def is_xml_name(text: str) -> bool:
    return _NAME_RE.fullmatch(text) is not None


def canonical_key(name: str) -> bytes:
    """D-RCML-4: siblings sort by the bytes of their names in UTF-8."""
    return name.encode("utf-8")


def seconds(text: str | None, default: float | None = None) -> float | None:
    """D-RCML-7 numbers of seconds."""
    if text is None:
        return default
    if not _SECONDS.fullmatch(text):
        raise RcmlError(f"not a number of seconds: {text!r}")
    value = float(text)
    if not (value > 0 and math.isfinite(value)):
        raise RcmlError(f"not a positive finite number of seconds: {text!r}")
    return value


def to_float32(value: float) -> float:
    return struct.unpack("!f", struct.pack("!f", value))[0]


@dataclass
class Node:
    kind: str  # "root", "group", "access" or "data"
    name: str
    path: str
    parent: Node | None
    perm: str  # effective permission: "rw", "r", "w" or ""
    children: dict[str, Node] = field(default_factory=dict)
    # access nodes
    atype: str = "normal"
    read_interval: float | None = None
    write_interval: float | None = None
    read_timeout: float = 10.0
    write_timeout: float = 10.0
    # data nodes
    dtype: str = ""
    count: int = 1
    size: int = 0
    lo: float | int | None = None
    hi: float | int | None = None

    def sorted_children(self) -> list[Node]:
        return [self.children[k] for k in sorted(self.children, key=canonical_key)]

    def data(self, right: str | None = None) -> list[Node]:
        """The data nodes of an access in canonical order, those with `right` only if given."""
        return [n for n in self.sorted_children() if right is None or right in n.perm]

    # -- the binary value format (D-RCML-9 to D-RCML-12) --

    def max_size(self) -> int:
        one = 2 + self.size if self.dtype in ("string", "bytes") else element_size(self.dtype)
        return one * self.count

    def default(self) -> Any:
        one: Any
        if self.dtype == "bool":
            one = False
        elif self.dtype == "string":
            one = ""
        elif self.dtype == "bytes":
            one = b""
        elif self.dtype in _FLOATS:
            one = 0.0 if self.lo is None or self.lo <= 0 else float(self.lo)
        else:
            one = 0 if self.lo is None or self.lo <= 0 else int(self.lo)
        return one if self.count == 1 else tuple([one] * self.count)

    def encode(self, value: Any, little16: bool = False) -> bytes:
        items = [value] if self.count == 1 else list(value)
        return b"".join(_encode_one(self.dtype, v, little16) for v in items)

    def decode(self, buf: bytes, pos: int, quirks: Collection[str] = ()) -> tuple[Any, int]:
        """One value from buf at pos; raises Malformed when it does not decode.

        `quirks` are fault names (main.py --fault) that make decoding too lenient.
        """
        items = []
        for _ in range(self.count):
            one, pos = _decode_one(self, buf, pos, quirks)
            items.append(one)
        return (items[0] if self.count == 1 else tuple(items)), pos

    def in_range(self, value: Any) -> bool:
        if self.lo is None and self.hi is None:
            return True
        items = [value] if self.count == 1 else list(value)
        for v in items:
            if isinstance(v, float) and math.isnan(v):
                return False
            if self.lo is not None and v < self.lo:
                return False
            if self.hi is not None and v > self.hi:
                return False
        return True


def element_size(dtype: str) -> int:
    if dtype == "bool":
        return 1
    if dtype in _INTS:
        return _INTS[dtype][1]
    return _FLOATS[dtype][1]


def _encode_one(dtype: str, v: Any, little16: bool) -> bytes:
    if dtype == "bool":
        return b"\x01" if v else b"\x00"
    if dtype in _INTS:
        code = _INTS[dtype][0]
        order = "<" if little16 and code in "hH" else "!"
        return struct.pack(order + code, v)
    if dtype in _FLOATS:
        return struct.pack("!" + _FLOATS[dtype][0], v)
    raw = v.encode("utf-8") if dtype == "string" else bytes(v)
    return struct.pack("!H", len(raw)) + raw


def _decode_one(node: Node, buf: bytes, pos: int, quirks: Collection[str]) -> tuple[Any, int]:
    dtype = node.dtype
    if dtype in ("string", "bytes"):
        if pos + 2 > len(buf):
            raise Malformed("length cut short")
        (n,) = struct.unpack_from("!H", buf, pos)
        pos += 2
        if n > node.size and "string-size-unchecked" not in quirks:
            raise Malformed(f"length {n} above size {node.size}")
        if pos + n > len(buf):
            raise Malformed("value cut short")
        raw = bytes(buf[pos : pos + n])
        if dtype == "bytes":
            return raw, pos + n
        try:
            return raw.decode("utf-8"), pos + n
        except UnicodeDecodeError as exc:
            raise Malformed("string is not UTF-8") from exc
    size = element_size(dtype)
    if pos + size > len(buf):
        raise Malformed("value cut short")
    if dtype == "bool":
        byte = buf[pos]
        if byte > 1 and "bool-nonzero-true" not in quirks:
            raise Malformed(f"bool byte 0x{byte:02x}")
        return byte != 0, pos + 1
    code = _INTS[dtype][0] if dtype in _INTS else _FLOATS[dtype][0]
    return struct.unpack_from("!" + code, buf, pos)[0], pos + size


def decode_run(
    nodes: list[Node], body: bytes, quirks: Collection[str] = (), check_range: bool = True
) -> list[Any]:
    """The values of nodes, one after another, filling body exactly and each within range."""
    values, pos = [], 0
    for node in nodes:
        value, pos = node.decode(body, pos, quirks)
        if check_range and not node.in_range(value):
            raise Malformed(f"{node.path}: value outside its range")
        values.append(value)
    if pos != len(body):
        raise Malformed(f"{len(body) - pos} bytes after the values")
    return values


def _bound(node: Node, text: str | None) -> float | int | None:
    if text is None:
        return None
    if node.dtype in _INTS:
        if not _INTEGER.fullmatch(text):
            raise RcmlError(f"{node.path}: bad bound {text!r}")
        return int(text)
    if node.dtype in _FLOATS:
        if not _DOUBLE.fullmatch(text):
            raise RcmlError(f"{node.path}: bound {text!r} is not a finite number")
        value = float(text)
        return to_float32(value) if node.dtype == "float32" else value
    raise RcmlError(f"{node.path}: min/max on a {node.dtype} node")


# -- reading the document --

_PERMS = {"rw": "rw", "r": "r", "w": "w", "none": ""}
_ALLOWED = {
    "rcml": {
        "version",
        "site",
        "timeSource",
        "timePrecision",
        "title",
        "author",
        "info",
        "contact",
    },
    "group": {"name", "permission"},
    "access": {
        "name",
        "type",
        "permission",
        "readInterval",
        "writeInterval",
        "readTimeout",
        "writeTimeout",
    },
    "data": {"name", "type", "permission", "count", "size", "min", "max"},
    "link": {"kind", "href", "title"},
    "meta": {"name", "content"},
}
_PARENTS = {
    "group": {"rcml", "group"},
    "access": {"rcml", "group"},
    "data": {"access"},
    "link": {"rcml", "group", "access", "data"},
    "meta": {"rcml", "group", "access", "data"},
}


@dataclass
class Robot:
    root: Node
    site: str
    site_path: str
    title: str
    links: list[tuple[str, str]]  # (kind, href)
    nodes: dict[str, Node]  # by path, "/" included


def _refuse(*_: object) -> None:
    raise RcmlError("DTD declarations and entities are not read (D-XML-3, D-XML-4)")


def parse(raw: bytes) -> Robot:
    if len(raw) > MAX_DOCUMENT:
        raise RcmlError("document larger than 16 MiB (D-XML-5)")
    parser = expat.ParserCreate(namespace_separator=" ")
    parser.SetParamEntityParsing(expat.XML_PARAM_ENTITY_PARSING_NEVER)

    def doctype(_name: str, _sysid: str | None, _pubid: str | None, internal: int) -> None:
        if internal:
            raise RcmlError("internal DTD subset (R-XML-2)")

    parser.StartDoctypeDeclHandler = doctype
    parser.EntityDeclHandler = _refuse
    parser.SkippedEntityHandler = _refuse
    parser.ExternalEntityRefHandler = _refuse  # type: ignore[assignment]
    stack: list[tuple[str, Node | None]] = []  # (element, node); "" for a skipped element
    skipping = [0]
    robot: dict[str, Any] = {"links": [], "nodes": {}}

    def start(tag: str, attrs: dict[str, str]) -> None:
        if len(stack) >= MAX_DEPTH:
            raise RcmlError("elements nested deeper than 256 (D-XML-5)")
        if skipping[0] or " " in tag:
            skipping[0] += 1
            stack.append(("", None))
            return
        attrs = {k: v for k, v in attrs.items() if " " not in k}
        parent_tag, parent = stack[-1] if stack else ("", None)
        if not stack:
            if tag != "rcml":
                raise RcmlError(f"root element <{tag}> is not rcml")
        elif parent_tag not in _PARENTS.get(tag, ()):
            raise RcmlError(f"<{tag}> inside <{parent_tag}>")
        unknown = set(attrs) - _ALLOWED[tag]
        if unknown:
            raise RcmlError(f"<{tag}> has unknown attributes {sorted(unknown)}")
        stack.append((tag, _element(tag, attrs, parent, robot)))

    def end(_tag: str) -> None:
        tag, _node = stack.pop()
        if not tag:
            skipping[0] = max(0, skipping[0] - 1)

    def text(data: str) -> None:
        if not skipping[0] and data.strip():
            raise RcmlError("character data in an RCML element (R-XML-9)")

    parser.StartElementHandler = start
    parser.EndElementHandler = end
    parser.CharacterDataHandler = text
    try:
        parser.Parse(raw, True)
    except expat.ExpatError as exc:
        raise RcmlError(f"not well-formed: {exc}") from exc
    if "root" not in robot:
        raise RcmlError("no rcml element")
    return Robot(
        robot["root"],
        robot["site"],
        robot["site_path"],
        robot["title"],
        robot["links"],
        robot["nodes"],
    )


_SITE = re.compile(r"rctp://(\[[0-9A-Fa-f:.]+\]|[^/:?#@\[\]]+)(?::([0-9]{1,5}))?(/[^?#]*)?")


def _element(
    tag: str, attrs: dict[str, str], parent: Node | None, robot: dict[str, Any]
) -> Node | None:
    if tag == "rcml":
        if attrs.get("version") != "2.0":
            raise RcmlError("rcml/@version is not 2.0")
        site = attrs.get("site", "")
        match = _SITE.fullmatch(site)
        if not match:
            raise RcmlError(f"bad site {site!r}")
        root = Node("root", "", "/", None, "rw")
        robot.update(
            root=root, site=site, site_path=match.group(3) or "/", title=attrs.get("title", "")
        )
        robot["nodes"]["/"] = root
        return root
    if tag == "link":
        if parent is not None and parent.kind == "root":
            robot["links"].append((attrs.get("kind", ""), attrs.get("href", "")))
        return None
    if tag == "meta":
        return None
    assert parent is not None
    name = attrs.get("name", "")
    if not is_xml_name(name) or len(name.encode("utf-8")) > 255:
        raise RcmlError(f"bad node name {name!r}")
    if name in parent.children:
        raise RcmlError(f"two siblings named {name!r}")
    path = ("" if parent.path == "/" else parent.path) + "/" + name
    if len(path.encode("utf-8")) > 1024:
        raise RcmlError(f"path longer than 1024 bytes: {path}")
    own = attrs.get("permission")
    if own is not None and own not in _PERMS:
        raise RcmlError(f"{path}: bad permission {own!r}")
    perm = parent.perm if own is None else "".join(c for c in _PERMS[own] if c in parent.perm)
    node = Node(tag, name, path, parent, perm)
    if tag == "access":
        node.atype = attrs.get("type", "normal")
        if node.atype not in ("normal", "event", "stream"):
            raise RcmlError(f"{path}: bad access type {node.atype!r}")
        node.read_interval = seconds(attrs.get("readInterval"))
        node.write_interval = seconds(attrs.get("writeInterval"))
        node.read_timeout = seconds(attrs.get("readTimeout"), 10.0) or 10.0
        node.write_timeout = seconds(attrs.get("writeTimeout"), 10.0) or 10.0
    elif tag == "data":
        dtype = attrs.get("type", "")
        node.dtype = ALIASES.get(dtype, dtype)
        if node.dtype not in TYPES:
            raise RcmlError(f"{path}: unknown type {dtype!r}")
        node.count = _small_int(attrs.get("count", "1"), path)
        if node.dtype in ("string", "bytes"):
            node.size = _small_int(attrs.get("size", ""), path)
        elif "size" in attrs:
            raise RcmlError(f"{path}: size on a {node.dtype} node")
        node.lo, node.hi = _bound(node, attrs.get("min")), _bound(node, attrs.get("max"))
        if node.lo is not None and node.hi is not None and node.lo > node.hi:
            raise RcmlError(f"{path}: min above max")
        if node.max_size() > 1024 * 1024:
            raise RcmlError(f"{path}: larger than 1 MiB")
    parent.children[name] = node
    robot["nodes"][path] = node
    return node


def _small_int(text: str, path: str) -> int:
    if not re.fullmatch(r"[0-9]{1,5}", text) or not 1 <= int(text) <= 65535:
        raise RcmlError(f"{path}: count or size {text!r} not in 1..65535")
    return int(text)


def check_streams(robot: Robot) -> None:
    """R-RCML-12, R-RCML-22: what a server needs of its stream accesses."""
    for node in robot.nodes.values():
        if node.kind != "access" or node.atype != "stream":
            continue
        for right, interval in (("r", node.read_interval), ("w", node.write_interval)):
            nodes = node.data(right)
            if nodes and interval is None:
                raise RcmlError(f"{node.path}: a stream with {right} nodes needs its interval")
            if sum(n.max_size() for n in nodes) > 65000:
                raise RcmlError(f"{node.path}: more than 65,000 bytes in one direction")
