"""Walk an RCML 2.0 tree: report every broken rule (specs/rcml-2.0.md §3) and build the model.

The element table (`rcml.schema`) covers attributes, lexical forms and placement; this module adds
what a table cannot say: names and paths, permission ceilings, types, sizes, timing.

A robot may have 100,000 data nodes, and checking each one element by element costs about 5 µs
in Python. Nearly all of them are plain (a name, a type, perhaps a permission, count or size, and
nothing inside), so an access whose data children are all plain and pass a few checks made once
over all of them (one regular expression over every name, one set for duplicates, one memo for the
rest) takes a fast path that builds its nodes directly. Anything unusual sends the whole access
element by element; the fast path reports nothing, so every diagnostic comes from one place.
"""

from __future__ import annotations

import re
from operator import attrgetter
from pathlib import Path
from urllib.parse import unquote, urlsplit

from rcmlconf.errors import ValueTextError
from rcmlconf.markup.document import XmlElement
from rcmlconf.markup.lexical import ASCII_NAME_PATTERN, absolute_uri
from rcmlconf.markup.structure import Attributes, Checker, ElementDef, parser_of
from rcmlconf.rcml.model import (
    DEFAULT_TIMEOUT,
    ROOT_PERMISSION,
    AccessNode,
    AccessType,
    DataNode,
    GroupNode,
    Link,
    Meta,
    Node,
    Permission,
    RcmlDocument,
)
from rcmlconf.rcml.schema import ELEMENTS
from rcmlconf.rcml.url import RctpUrl
from rcmlconf.values import ValueType
from rcmlconf.values.declared import Number, Problem, declared_bounds, declared_type

#: D-RCML-3, D-RCML-13, D-RCML-15, D-RCML-17.
MAX_NAME_BYTES = 255
MAX_PATH_BYTES = 1024
MAX_STREAM_BYTES = 65000
UNFRAGMENTED_BYTES = 1200
TIME_SOURCES = ("GPS", "NTP", "PTP", "local")
LINK_KINDS = ("UserInterface", "Documentation", "RobotModel")

_ROOT = ELEMENTS["rcml"]
_GROUP = ELEMENTS["group"]
_ACCESS = ELEMENTS["access"]
_DATA = ELEMENTS["data"]
_LINK = ELEMENTS["link"]
_META = ELEMENTS["meta"]
_TIMING = ("readInterval", "writeInterval", "readTimeout", "writeTimeout")

#: What a plain data node's attributes make: type, effective permission, min, max.
_Kind = tuple[ValueType, Permission, Number | None, Number | None]

#: Attributes a data node may have and still take the fast path.
_PLAIN_DATA = frozenset({"name", "type", "permission", "count", "size", "min", "max"})
#: ASCII names, one a line (others take the element-by-element path, which knows all of XML's).
_NAME_LINES = re.compile(f"(?:{ASCII_NAME_PATTERN}\n)*{ASCII_NAME_PATTERN}")
_by_name = attrgetter("name")
_parse_type, _parse_count, _parse_size, _parse_permission = (
    parser_of(_DATA, name) for name in ("type", "count", "size", "permission")
)


def load_rcml(checker: Checker, base_dir: Path | None = None) -> RcmlDocument | None:
    """The document's model, or None when the checker recorded any error.

    `base_dir` is the file's directory, for the existence check of R-RCML-27; None skips it.
    """
    return RcmlWalk(checker, base_dir).document(checker.document.root)


def load(checker: Checker, base_dir: Path | None, resolve: object) -> RcmlDocument | None:
    """The validator's entry point (`validate.languages`); RCML refers to no other document."""
    return load_rcml(checker, base_dir)


class RcmlWalk:
    """One document's elements to its model, with a fast path for plain data nodes (checked
    against the element-by-element path by the tests)."""

    def __init__(self, checker: Checker, base_dir: Path | None) -> None:
        self.check = checker
        self.base_dir = base_dir
        self.nodes: dict[str, Node] = {}
        # Plain data nodes by attribute texts and inherited permission (a document repeats few).
        self._plain: dict[tuple[str | None, ...], _Kind | None] = {}

    # -- the root ------------------------------------------------------------------------------

    def document(self, root: XmlElement) -> RcmlDocument | None:
        attrs = self.check.attributes(root, _ROOT)
        time_source = attrs.text("timeSource") or "local"
        if time_source not in TIME_SOURCES:
            self.check.warning(
                "R-RCML-3",
                root,
                f"timeSource {time_source!r} is not one of {', '.join(TIME_SOURCES)}",
                "timeSource",
            )
        contact = attrs.text("contact")
        if contact is not None:
            try:
                absolute_uri(contact)
            except ValueTextError as exc:
                self.check.warning("R-RCML-5", root, f"contact: {exc}", "contact")
        children, links, meta = self._children(root, _ROOT, "", ROOT_PERMISSION)
        if self.check.error_count:
            return None
        site = attrs["site"]
        assert isinstance(site, RctpUrl)  # the element table's form for `site`
        return RcmlDocument(
            site=site,
            children=children,
            time_source=time_source,
            time_precision=attrs.number("timePrecision"),
            title=attrs.text("title"),
            author=attrs.text("author"),
            info=attrs.text("info"),
            contact=contact,
            links=links,
            meta=meta,
            nodes=self.nodes,
        )

    # -- shared by every node --------------------------------------------------------------------

    def _children(
        self, element: XmlElement, spec: ElementDef, path: str, permission: Permission
    ) -> tuple[tuple[GroupNode | AccessNode, ...], tuple[Link, ...], tuple[Meta, ...]]:
        """The group and access children of the root or a group, with its links and metadata."""
        nodes: list[GroupNode | AccessNode] = []
        links: list[Link] = []
        meta: list[Meta] = []
        names: set[str] = set()
        for child in self.check.children(element, spec):
            tag = child.tag
            node: GroupNode | AccessNode | None
            if tag == "group":
                node = self._group(child, path, permission, names)
            elif tag == "access":
                node = self._access(child, path, permission, names)
            else:
                self._annotation(child, links, meta)
                continue
            if node is not None:
                nodes.append(node)
        nodes.sort(key=_by_name)
        return tuple(nodes), tuple(links), tuple(meta)

    def _annotation(self, element: XmlElement, links: list[Link], meta: list[Meta]) -> None:
        if element.tag == "link":
            link = self._link(element)
            if link is not None:
                links.append(link)
            return
        attrs = self.check.attributes(element, _META)
        self.check.leaf(element, _META)
        name, content = attrs.text("name"), attrs.text("content")
        if name is not None and content is not None:
            meta.append(Meta(name, content))

    def _node(
        self,
        element: XmlElement,
        spec: ElementDef,
        parent: str,
        inherited: Permission,
        siblings: set[str],
    ) -> tuple[Attributes, str, str, Permission]:
        """Attributes, name, path and effective permission of a group, access or data element.

        A node without a valid name gets the name `?` so that its content is still checked; the
        error already recorded keeps the model from being returned.
        """
        attrs = self.check.attributes(element, spec)
        permission_text = attrs.get("permission")
        permission = (
            inherited
            if permission_text is None
            else self._permission(element, str(permission_text), inherited)
        )
        name = attrs.get("name")
        if not isinstance(name, str):
            return attrs, "?", f"{parent}/?", permission
        # A name or path this short cannot reach its limit in bytes: skip the encoding.
        if len(name) > MAX_NAME_BYTES // 4 and len(name.encode()) > MAX_NAME_BYTES:
            self.check.error(
                "R-RCML-7",
                element,
                f"name is {len(name.encode())} bytes, more than {MAX_NAME_BYTES}",
                "name",
            )
        if name in siblings:
            self.check.error(
                "R-RCML-8",
                element,
                f"a sibling is already named {name!r}; sibling names are distinct",
                "name",
            )
        siblings.add(name)
        path = f"{parent}/{name}"
        if len(path) > MAX_PATH_BYTES // 4 and len(path.encode()) > MAX_PATH_BYTES:
            self.check.error(
                "R-RCML-9",
                element,
                f"path is {len(path.encode())} bytes, more than {MAX_PATH_BYTES}",
                "name",
            )
        return attrs, name, path, permission

    def _permission(self, element: XmlElement, text: str, inherited: Permission) -> Permission:
        """D-RCML-8: a node narrows what it inherits and may not widen it."""
        own = Permission.from_text(text)
        extra = own & ~inherited
        if extra:
            self.check.error(
                "R-RCML-16",
                element,
                f'permission="{text}" grants {extra.to_text()}, which the enclosing node withholds '
                f"(it grants {inherited.to_text()})",
                "permission",
                "permission can only narrow what the parent grants",
            )
        return own & inherited

    # -- group, access, data ---------------------------------------------------------------------

    def _group(
        self, element: XmlElement, parent: str, inherited: Permission, siblings: set[str]
    ) -> GroupNode:
        _, name, path, permission = self._node(element, _GROUP, parent, inherited, siblings)
        children, links, meta = self._children(element, _GROUP, path, permission)
        node = GroupNode(path, name, permission, children, links, meta)
        self.nodes[path] = node
        return node

    def _access(
        self, element: XmlElement, parent: str, inherited: Permission, siblings: set[str]
    ) -> AccessNode:
        attrs, name, path, permission = self._node(element, _ACCESS, parent, inherited, siblings)
        links: list[Link] = []
        meta: list[Meta] = []
        children = self.check.children(element, _ACCESS)
        data_elements = [child for child in children if child.tag == "data"]
        data = self._plain_data(data_elements, path, permission)
        if data is None:
            names: set[str] = set()
            data = [
                node
                for child in data_elements
                if (node := self._data(child, path, permission, names)) is not None
            ]
        for child in children:
            if child.tag != "data":
                self._annotation(child, links, meta)
        data.sort(key=_by_name)
        access = AccessNode(
            path,
            name,
            AccessType(attrs.text("type") or "normal"),
            permission,
            tuple(data),
            attrs.number("readInterval"),
            attrs.number("writeInterval"),
            attrs.number("readTimeout") or DEFAULT_TIMEOUT,
            attrs.number("writeTimeout") or DEFAULT_TIMEOUT,
            tuple(links),
            tuple(meta),
        )
        if not data_elements:
            self.check.warning("R-RCML-24", element, "access holds no data node")
        self._timing(element, attrs, access)
        self.nodes[path] = access
        return access

    def _timing(self, element: XmlElement, attrs: Attributes, node: AccessNode) -> None:
        """R-RCML-12, -13, -14, -22, -23: intervals, timeouts and sizes of a stream."""
        if node.type is not AccessType.STREAM:
            for name in _TIMING:
                if name in attrs:
                    self.check.warning(
                        "R-RCML-13",
                        element,
                        f"{name} means nothing on {node.type.value} access",
                        name,
                    )
            return
        for direction, nodes, interval, timeout, verb in (
            ("read", node.readable(), node.read_interval, node.read_timeout, "readable"),
            ("write", node.writable(), node.write_interval, node.write_timeout, "writable"),
        ):
            interval_name, timeout_name = f"{direction}Interval", f"{direction}Timeout"
            if not nodes:
                for name in (interval_name, timeout_name):
                    if name in attrs:
                        self.check.warning(
                            "R-RCML-13",
                            element,
                            f"{name} means nothing: no data node is {verb}",
                            name,
                        )
                continue
            if interval is None:
                if interval_name not in element.attrs:  # a malformed one is reported already
                    self.check.error(
                        "R-RCML-12",
                        element,
                        f"stream access with {verb} data has no {interval_name}",
                    )
            elif timeout < 2 * interval:
                given = "" if timeout_name in attrs else " (the default)"
                self.check.warning(
                    "R-RCML-14",
                    element,
                    f"{timeout_name} {timeout:g} s{given} is less than twice "
                    f"{interval_name} {interval:g} s",
                    timeout_name if timeout_name in attrs else interval_name,
                )
            total = sum(d.type.max_encoded_size for d in nodes)
            if total > MAX_STREAM_BYTES:
                self.check.error(
                    "R-RCML-22",
                    element,
                    f"{verb} data add up to {total:,} bytes, more than "
                    f"{MAX_STREAM_BYTES:,} for one data-stream payload",
                )
            elif total > UNFRAGMENTED_BYTES:
                self.check.warning(
                    "R-RCML-23",
                    element,
                    f"{verb} data add up to {total:,} bytes, more than "
                    f"{UNFRAGMENTED_BYTES:,}: packets will be fragmented",
                )

    def _plain_data(
        self, elements: list[XmlElement], parent: str, inherited: Permission
    ) -> list[DataNode] | None:
        """The data nodes, when every element is plain and valid; None sends them one by one."""
        names: list[str] = []
        kinds: list[_Kind] = []
        memo = self._plain
        ceiling = inherited.to_text()
        for element in elements:
            attrs = element.attrs
            if element.children or element.has_text or not attrs.keys() <= _PLAIN_DATA:
                return None
            name = attrs.get("name")
            key = (
                attrs.get("type"),
                attrs.get("count"),
                attrs.get("size"),
                attrs.get("permission"),
                attrs.get("min"),
                attrs.get("max"),
                ceiling,
            )
            try:
                kind = memo[key]
            except KeyError:
                kind = memo[key] = _plain_kind(key[:6], inherited)
            if kind is None or name is None:
                return None
            names.append(name)
            kinds.append(kind)
        if not names:
            return []
        longest = max(map(len, names))
        if (
            len(set(names)) != len(names)
            or _NAME_LINES.fullmatch("\n".join(names)) is None
            or longest > MAX_NAME_BYTES // 4
            or len(parent) + 1 + longest > MAX_PATH_BYTES // 4
        ):
            return None
        prefix = parent + "/"
        paths = [prefix + name for name in names]
        # tuple.__new__ is what DataNode(...) does after filling in defaults, at C speed.
        nodes = [
            tuple.__new__(DataNode, (path, name, vtype, permission, low, high, (), ()))
            for path, name, (vtype, permission, low, high) in zip(paths, names, kinds, strict=True)
        ]
        self.nodes.update(zip(paths, nodes, strict=True))
        return nodes

    def _data(
        self, element: XmlElement, parent: str, inherited: Permission, siblings: set[str]
    ) -> DataNode | None:
        attrs, name, path, permission = self._node(element, _DATA, parent, inherited, siblings)
        links: list[Link] = []
        meta: list[Meta] = []
        if element.children or element.has_text:
            for child in self.check.children(element, _DATA):
                self._annotation(child, links, meta)
        vtype = self._value_type(element, attrs)
        if vtype is None:
            return None
        low, high = self._bounds(element, attrs, vtype)
        node = DataNode(path, name, vtype, permission, low, high, tuple(links), tuple(meta))
        self.nodes[path] = node
        return node

    def _value_type(self, element: XmlElement, attrs: Attributes) -> ValueType | None:
        """R-RCML-18 and -21, which depend on `type`, `count` and `size` alone."""
        vtype, problems = declared_type(
            attrs.text("type"), attrs.integer("count"), attrs.integer("size")
        )
        self._report(element, problems)
        return vtype

    def _bounds(
        self, element: XmlElement, attrs: Attributes, vtype: ValueType
    ) -> tuple[Number | None, Number | None]:
        """R-RCML-20, which depends on the type, `min` and `max` alone."""
        low, high, problems = declared_bounds(vtype, attrs.text("min"), attrs.text("max"))
        self._report(element, problems)
        return low, high

    def _report(self, element: XmlElement, problems: tuple[Problem, ...]) -> None:
        for rule, message, attribute, hint in problems:
            self.check.error(rule, element, message, attribute, hint)

    # -- link ------------------------------------------------------------------------------------

    def _link(self, element: XmlElement) -> Link | None:
        attrs = self.check.attributes(element, _LINK)
        self.check.leaf(element, _LINK)
        kind, href = attrs.text("kind"), attrs.text("href")
        if kind is None or href is None:
            return None
        if kind not in LINK_KINDS:
            self.check.warning(
                "R-RCML-26",
                element,
                f"link kind {kind!r} is not one of {', '.join(LINK_KINDS)}",
                "kind",
            )
        elif kind == "UserInterface" and self.base_dir is not None:
            self._local_link(element, href)
        return Link(kind, href, attrs.text("title"))

    def _local_link(self, element: XmlElement, href: str) -> None:
        """R-RCML-27: look (never read) for the RXID file a relative link names."""
        parts = urlsplit(href)
        if parts.scheme or parts.netloc or parts.path.startswith("/") or not parts.path:
            return
        assert self.base_dir is not None
        if not (self.base_dir / unquote(parts.path)).is_file():
            self.check.warning(
                "R-RCML-27", element, f"the user interface {href!r} is not beside this file", "href"
            )


def _plain_kind(texts: tuple[str | None, ...], inherited: Permission) -> _Kind | None:
    """Type, effective permission and range of a plain data node, if every attribute is valid.

    Uses the element table's own lexical forms and the same checks as the element walk, so it
    accepts exactly what the element walk accepts without a finding.
    """
    type_text, count_text, size_text, permission_text, low_text, high_text = texts
    try:
        type_name = _parse_type(type_text) if type_text is not None else None
        count = _parse_count(count_text) if count_text is not None else None
        size = _parse_size(size_text) if size_text is not None else None
        if permission_text is not None:
            _parse_permission(permission_text)
    except ValueTextError:
        return None
    assert type_name is None or isinstance(type_name, str)
    assert count is None or isinstance(count, int)
    assert size is None or isinstance(size, int)
    vtype, problems = declared_type(type_name, count, size)
    if vtype is None or problems:
        return None
    low, high, problems = declared_bounds(vtype, low_text, high_text)
    if problems:
        return None
    permission = inherited
    if permission_text is not None:
        permission = Permission.from_text(permission_text)
        if permission & ~inherited:
            return None
    return vtype, permission, low, high
