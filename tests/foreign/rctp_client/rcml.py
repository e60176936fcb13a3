"""RCML 2.0 as a client needs it: the node tree (specs/rcml-2.0.md) read under the XML
profile of specs/xml.md, and the binary value format (D-RCML-9 to D-RCML-12)."""

from __future__ import annotations

import codecs
import math
import re
import struct
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any
from xml.parsers import expat

MAX_DOCUMENT = 16 * 1024 * 1024  # D-XML-5
MAX_DEPTH = 256

_START = (
    ":A-Z_a-z\u00c0-\u00d6\u00d8-\u00f6\u00f8-\u02ff\u0370-\u037d\u037f-\u1fff"
    "\u200c-\u200d\u2070-\u218f\u2c00-\u2fef\u3001-\ud7ff\uf900-\ufdcf\ufdf0-\ufffd"
    "\U00010000-\U000effff"
)
_NAME = re.compile(f"[{_START}][{_START}\\-.0-9\u00b7\u0300-\u036f\u203f-\u2040]*")
_SECONDS = re.compile(r"\+?([0-9]+(\.[0-9]*)?|\.[0-9]+)([eE][+-]?[0-9]+)?")
_INTEGER = re.compile(r"[+-]?[0-9]+")
_DOUBLE = re.compile(r"[+-]?([0-9]+(\.[0-9]*)?|\.[0-9]+)([eE][+-]?[0-9]+)?")
_ENCODING = re.compile(rb"<\?xml[^>]*?encoding\s*=\s*[\"']([A-Za-z][A-Za-z0-9._-]*)[\"']")

NUMERIC = {
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
TYPES = set(NUMERIC) | {"bool", "string", "bytes"}
TIMING = ("readInterval", "writeInterval", "readTimeout", "writeTimeout")


class RcmlError(Exception):
    """The document cannot be used (not well-formed, refused by the profile, or invalid)."""


class BadValue(ValueError):
    """A value that does not decode, or lies outside its node's range."""


def is_xml_name(text: str) -> bool:
    return bool(_NAME.fullmatch(text)) and len(text.encode("utf-8")) <= 255


def canonical(names: list[str]) -> list[str]:
    """D-RCML-4: siblings sorted by the bytes of their names in UTF-8."""
    return sorted(names, key=lambda n: n.encode("utf-8"))


@dataclass
class Node:
    kind: str  # "root", "group", "access" or "data"
    name: str
    path: str
    perm: str  # effective permission: "rw", "r", "w" or ""
    parent: Node | None = None
    children: dict[str, Node] = field(default_factory=dict)
    atype: str = "normal"
    timing: dict[str, float] = field(default_factory=dict)
    dtype: str = ""
    count: int = 1
    size: int = 0
    lo: float | int | None = None
    hi: float | int | None = None
    doc_index: int = 0

    @property
    def readable(self) -> bool:
        return "r" in self.perm

    @property
    def writable(self) -> bool:
        return "w" in self.perm

    def data_nodes(self, want: str = "") -> list[Node]:
        """The data children of an access, in canonical order (with `want` among r/w)."""
        out = [c for c in self.children.values() if c.kind == "data" and want in c.perm]
        return sorted(out, key=lambda c: c.name.encode("utf-8"))

    def walk(self) -> list[Node]:
        """This node and all below it, siblings in document order (children keep it)."""
        out: list[Node] = [self]
        for child in self.children.values():
            out.extend(child.walk())
        return out


@dataclass
class Model:
    root: Node
    site: str
    time_precision: float
    nodes: dict[str, Node]

    def site_path(self) -> str:
        m = re.match(r"rctp://(\[[^\]]*\]|[^/:]*)(:[0-9]+)?(/.*)?$", self.site)
        return (m.group(3) or "/") if m else "/"


# ---- the binary value format -------------------------------------------------------------


def _f32(x: float) -> float:
    return float(struct.unpack(">f", struct.pack(">f", x))[0])


def _bound(node: Node, text: str | None) -> float | int | None:
    if text is None:
        return None
    if node.dtype not in NUMERIC:
        raise RcmlError(f"{node.path}: min/max on a {node.dtype} node")
    if node.dtype.startswith(("int", "uint")):
        if not _INTEGER.fullmatch(text):
            raise RcmlError(f"{node.path}: bad bound {text!r}")
        return int(text)
    if not _DOUBLE.fullmatch(text):
        raise RcmlError(f"{node.path}: bad bound {text!r}")
    value = float(text)
    if node.dtype == "float32":
        try:
            value = _f32(value)
        except OverflowError as e:
            raise RcmlError(f"{node.path}: bound {text!r} overflows float32") from e
    if not math.isfinite(value):
        raise RcmlError(f"{node.path}: bound {text!r} is not finite")
    return value


def _in_range(node: Node, v: float | int) -> bool:
    if isinstance(v, float) and math.isnan(v) and (node.lo is not None or node.hi is not None):
        return False
    if node.lo is not None and v < node.lo:
        return False
    return not (node.hi is not None and v > node.hi)


class Codec:
    """The binary value format; `faults` may make the sender (never the reader, but for
    bool-nonzero-accepted) get one detail wrong."""

    def __init__(self, faults: set[str] | frozenset[str] = frozenset()) -> None:
        self.faults = frozenset(faults)

    def _decode_one(self, node: Node, buf: bytes, off: int, ranged: bool) -> tuple[Any, int]:
        t = node.dtype
        if t == "bool":
            if off + 1 > len(buf):
                raise BadValue(f"{node.path}: cut short")
            if buf[off] > 1 and "bool-nonzero-accepted" not in self.faults:
                raise BadValue(f"{node.path}: bad bool")
            return buf[off] != 0, off + 1
        if t in ("string", "bytes"):
            if off + 2 > len(buf):
                raise BadValue(f"{node.path}: cut short")
            (n,) = struct.unpack_from(">H", buf, off)
            if n > node.size or off + 2 + n > len(buf):
                raise BadValue(f"{node.path}: length {n} too long or cut short")
            raw = bytes(buf[off + 2 : off + 2 + n])
            if t == "bytes":
                return raw, off + 2 + n
            try:
                return raw.decode("utf-8"), off + 2 + n
            except UnicodeDecodeError as e:
                raise BadValue(f"{node.path}: not UTF-8") from e
        fmt = ">" + NUMERIC[t]
        size = struct.calcsize(fmt)
        if off + size > len(buf):
            raise BadValue(f"{node.path}: cut short")
        (v,) = struct.unpack_from(fmt, buf, off)
        if ranged and not _in_range(node, v):
            raise BadValue(f"{node.path}: {v} outside its range")
        return v, off + size

    def decode(self, nodes: list[Node], buf: bytes, ranged: bool = True) -> list[Any]:
        """The values of `nodes`, one after another, filling `buf` exactly; with `ranged`,
        a value outside its node's min/max is refused too (D-RCML-12)."""
        out: list[Any] = []
        off = self.decode_prefix(nodes, buf, out, ranged)
        if off != len(buf):
            raise BadValue(f"{len(buf) - off} bytes after the values")
        return out

    def decode_prefix(self, nodes: list[Node], buf: bytes, out: list[Any], ranged: bool) -> int:
        """Decode `nodes` in turn, appending each value to `out`; the offset reached. A bad
        value raises BadValue with the values before it already in `out`."""
        off = 0
        for node in nodes:
            items = []
            for _ in range(node.count):
                item, off = self._decode_one(node, buf, off, ranged)
                items.append(item)
            out.append(items[0] if node.count == 1 else items)
        return off

    def _encode_one(self, node: Node, v: Any) -> bytes:
        t, faults = node.dtype, self.faults
        if t == "bool":
            if "bool-as-text" in faults:
                return b"1" if v else b"0"
            return b"\x01" if v else b"\x00"
        if t in ("string", "bytes"):
            raw = v.encode("utf-8") if t == "string" else bytes(v)
            n = len(v) if t == "string" and "string-length-in-characters" in faults else len(raw)
            return struct.pack(">H", n) + raw
        order = ">"
        if t in ("int16", "uint16") and "int16-little-endian" in faults:
            order = "<"
        if t == "float64" and "float64-little-endian" in faults:
            order = "<"
        return struct.pack(order + NUMERIC[t], v)

    def encode(self, nodes: list[Node], values: list[Any]) -> bytes:
        out = bytearray()
        for node, v in zip(nodes, values, strict=True):
            if node.count > 1 and "array-count-prefix" in self.faults:
                out += struct.pack(">H", node.count)
            for item in v if node.count > 1 else [v]:
                out += self._encode_one(node, item)
        return bytes(out)


def zero(node: Node) -> Any:
    """D-RCTP-31's zero value: 0, the bound of its range nearest 0, false, empty text or
    bytes; per element of an array."""
    if node.dtype == "bool":
        one: Any = False
    elif node.dtype == "string":
        one = ""
    elif node.dtype == "bytes":
        one = b""
    else:
        one = 0.0 if node.dtype.startswith("float") else 0
        if node.lo is not None and one < node.lo:
            one = node.lo
        if node.hi is not None and one > node.hi:
            one = node.hi
    return one if node.count == 1 else [one] * node.count


def text(value: Any) -> str:
    if isinstance(value, list):
        return "[" + ", ".join(text(v) for v in value) + "]"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, bytes):
        return value.hex()
    return str(value)


# ---- reading a document --------------------------------------------------------------------


def _seconds(node_path: str, attrs: dict[str, str], name: str) -> float | None:
    raw = attrs.get(name)
    if raw is None:
        return None
    if not _SECONDS.fullmatch(raw) or not 0 < float(raw) < math.inf:
        raise RcmlError(f"{node_path}: {name}={raw!r} is not a number of seconds")
    return float(raw)


def _decode_document(data: bytes) -> str:
    if data.startswith(codecs.BOM_UTF8):
        return data[3:].decode("utf-8")
    if data[:2] in (codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE):
        return data.decode("utf-16")
    m = _ENCODING.match(data[:512])
    encoding = m.group(1).decode("ascii") if m else "utf-8"
    try:
        return data.decode(encoding)
    except LookupError as e:
        raise RcmlError(f"unknown encoding {encoding}") from e


ATTRIBUTES = {
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
    "access": {"name", "type", "permission"} | set(TIMING),
    "data": {"name", "type", "permission", "count", "size", "min", "max"},
    "link": {"kind", "href", "title"},
    "meta": {"name", "content"},
}
REQUIRED = {"link": ("kind", "href"), "meta": ("name", "content")}


class _Builder:
    def __init__(self, foreign: bool) -> None:
        self.stack: list[Node | None] = []
        self.depth = 0
        self.skip = 0
        self.root: Node | None = None
        self.site = ""
        self.precision = 0.0
        self.count = 0
        self.foreign = foreign  # the read-foreign-namespace fault: elements by local name

    def start(self, name: str, attrs: dict[str, str]) -> None:
        self.depth += 1
        if self.depth > MAX_DEPTH:
            raise RcmlError("nested deeper than 256")
        if " " in name and self.foreign and not self.skip:
            name = name.rsplit(" ", 1)[1]
        if self.skip or " " in name:  # D-XML-6, R-XML-13: an extension, skipped with its content
            self.skip += 1
            return
        attrs = {k: v for k, v in attrs.items() if " " not in k}
        unknown = sorted(set(attrs) - ATTRIBUTES.get(name, set()))
        if name in ATTRIBUTES and unknown:
            raise RcmlError(f"<{name}> has an attribute RCML does not define: {unknown[0]}")
        parent = self.stack[-1] if self.stack else None
        self.count += 1
        if not self.stack:
            if name != "rcml" or attrs.get("version") != "2.0" or "site" not in attrs:
                raise RcmlError("the root is not <rcml version='2.0' site=...>")
            self.root = Node("root", "", "/", "rw")
            self.site = attrs["site"]
            self.precision = _seconds("/", attrs, "timePrecision") or 0.0
            self.stack.append(self.root)
            return
        if parent is None:
            raise RcmlError(f"<{name}> inside an empty element (link or meta)")
        if name in ("link", "meta"):
            if any(key not in attrs for key in REQUIRED[name]):
                raise RcmlError(f"<{name}> without {' or '.join(REQUIRED[name])}")
            self.stack.append(None)
            return
        allowed = {"group": ("root", "group"), "access": ("root", "group"), "data": ("access",)}
        if name not in allowed or parent is None or parent.kind not in allowed[name]:
            raise RcmlError(f"<{name}> is not allowed here")
        node_name = attrs.get("name", "")
        if not is_xml_name(node_name) or node_name in parent.children:
            raise RcmlError(f"bad or repeated name {node_name!r}")
        path = ("" if parent.path == "/" else parent.path) + "/" + node_name
        perm = attrs.get("permission")
        if perm is not None and perm not in ("r", "w", "rw", "none"):
            raise RcmlError(f"{path}: bad permission {perm!r}")
        eff = parent.perm if perm is None else "".join(c for c in "rw" if c in perm)
        eff = "".join(c for c in eff if c in parent.perm)  # a ceiling (D-RCML-8)
        node = Node(name, node_name, path, eff, parent, doc_index=self.count)
        if name == "access":
            node.atype = attrs.get("type", "normal")
            if node.atype not in ("normal", "event", "stream"):
                raise RcmlError(f"{path}: bad type {node.atype!r}")
            for key in TIMING:
                value = _seconds(path, attrs, key)
                if value is not None:
                    node.timing[key] = value
        elif name == "data":
            dtype = ALIASES.get(attrs.get("type", ""), attrs.get("type", ""))
            if dtype not in TYPES:
                raise RcmlError(f"{path}: bad type")
            node.dtype = dtype
            for key, lo, hi in (("count", 1, 65535), ("size", 1, 65535)):
                raw = attrs.get(key)
                if raw is not None:
                    if not raw.isascii() or not raw.isdigit() or not lo <= int(raw) <= hi:
                        raise RcmlError(f"{path}: bad {key}")
                    setattr(node, key, int(raw))
            if (dtype in ("string", "bytes")) != ("size" in attrs):
                raise RcmlError(f"{path}: size is required on string and bytes only")
            node.lo = _bound(node, attrs.get("min"))
            node.hi = _bound(node, attrs.get("max"))
        parent.children[node_name] = node
        self.stack.append(node)

    def end(self, name: str) -> None:
        self.depth -= 1
        if self.skip:
            self.skip -= 1
            return
        self.stack.pop()


def parse_rcml(
    data: bytes, load_dtd: Callable[[str], bytes | None] | None = None, foreign: bool = False
) -> Model:
    """Read an RCML document under xml.md: DTDs are never loaded, entities never expanded
    (D-XML-3, D-XML-4), extensions skipped (D-XML-6). `load_dtd` (the load-dtd fault) makes
    the parser fetch and apply the external DTD a DOCTYPE names; `foreign` is the
    read-foreign-namespace fault."""
    if len(data) > MAX_DOCUMENT:
        raise RcmlError("larger than 16 MiB")
    try:
        document = _decode_document(data)
    except UnicodeDecodeError as e:
        raise RcmlError(f"not in its encoding: {e}") from e
    builder = _Builder(foreign)
    parser = expat.ParserCreate("utf-8", " ")

    def doctype(_name: str, _sys: str | None, _pub: str | None, internal: int) -> None:
        if internal:
            raise RcmlError("internal DTD subset")

    def entity(*_args: object) -> None:
        raise RcmlError("entity declaration or reference")

    if load_dtd is None:
        parser.SetParamEntityParsing(expat.XML_PARAM_ENTITY_PARSING_NEVER)
        parser.EntityDeclHandler = entity
    else:

        def external(context: str | None, _base: str | None, system: str | None, _p: object) -> int:
            text = load_dtd(system or "")
            if text is not None:
                sub = parser.ExternalEntityParserCreate(context)
                sub.Parse(text, True)
            return 1

        parser.SetParamEntityParsing(expat.XML_PARAM_ENTITY_PARSING_UNLESS_STANDALONE)
        parser.ExternalEntityRefHandler = external
    parser.StartDoctypeDeclHandler = doctype
    parser.SkippedEntityHandler = entity
    parser.StartElementHandler = builder.start
    parser.EndElementHandler = builder.end
    try:
        parser.Parse(document.encode("utf-8"), True)
    except expat.ExpatError as e:
        raise RcmlError(f"not well-formed: {e}") from e
    if builder.root is None:
        raise RcmlError("no root element")
    nodes = {n.path: n for n in builder.root.walk()}
    return Model(builder.root, builder.site, builder.precision, nodes)
