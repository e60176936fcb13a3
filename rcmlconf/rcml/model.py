"""An RCML 2.0 document as data: the tree of nodes, each with its path and effective permission.

Children are kept in canonical order (D-RCML-4), never document order. Python compares `str` by
code point, which is the same order as comparing the UTF-8 bytes, so sorting by name suffices.

Nodes are immutable `NamedTuple`s rather than frozen dataclasses: a robot may have 100,000 of
them, and a frozen dataclass costs three times as much to create.
"""

from __future__ import annotations

import enum
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from typing import NamedTuple

from rcmlconf.rcml.url import RctpUrl
from rcmlconf.values import Value, ValueType, first_outside
from rcmlconf.values.declared import zero_value


class Permission(enum.Flag):
    """D-RCML-8. `none` is the empty flag."""

    NONE = 0
    READ = enum.auto()
    WRITE = enum.auto()

    @classmethod
    def from_text(cls, text: str) -> Permission:
        return _PERMISSIONS[text]

    def to_text(self) -> str:
        return _PERMISSION_TEXTS[self]


_PERMISSIONS = {
    "none": Permission.NONE,
    "r": Permission.READ,
    "w": Permission.WRITE,
    "rw": Permission.READ | Permission.WRITE,
}
_PERMISSION_TEXTS = {permission: text for text, permission in _PERMISSIONS.items()}
PERMISSION_TEXTS = tuple(_PERMISSIONS)
#: What the top of the tree grants (D-RCML-8).
ROOT_PERMISSION = Permission.READ | Permission.WRITE


class AccessType(enum.Enum):
    NORMAL = "normal"
    EVENT = "event"
    STREAM = "stream"


#: D-RCML-6: the timeouts of the paper's sample.
DEFAULT_TIMEOUT = 10.0


class Link(NamedTuple):
    kind: str
    href: str
    title: str | None = None


class Meta(NamedTuple):
    name: str
    content: str


class DataNode(NamedTuple):
    path: str
    name: str
    type: ValueType
    permission: Permission
    minimum: int | float | None = None
    maximum: int | float | None = None
    links: tuple[Link, ...] = ()
    meta: tuple[Meta, ...] = ()

    def zero(self) -> Value:
        """The node's zero value (D-RCTP-31): nearest 0 within its range, false, empty."""
        return zero_value(self.type, self.minimum, self.maximum)

    def out_of_range(self, value: Value) -> str | None:
        """Why a value breaks `min`/`max` (D-RCML-12, every item of an array), or None."""
        index = first_outside(value, self.minimum, self.maximum)
        if index is None:
            return None
        item = value[index] if isinstance(value, tuple) else value
        return f"{item!r} is outside {self.path}'s range {self.minimum} to {self.maximum}"


class AccessNode(NamedTuple):
    path: str
    name: str
    type: AccessType
    permission: Permission
    #: Canonical order (D-RCML-4).
    data: tuple[DataNode, ...]
    read_interval: float | None = None
    write_interval: float | None = None
    read_timeout: float = DEFAULT_TIMEOUT
    write_timeout: float = DEFAULT_TIMEOUT
    links: tuple[Link, ...] = ()
    meta: tuple[Meta, ...] = ()

    def readable(self) -> tuple[DataNode, ...]:
        return tuple(d for d in self.data if Permission.READ in d.permission)

    def writable(self) -> tuple[DataNode, ...]:
        return tuple(d for d in self.data if Permission.WRITE in d.permission)


class GroupNode(NamedTuple):
    path: str
    name: str
    permission: Permission
    #: Canonical order (D-RCML-4).
    children: tuple[GroupNode | AccessNode, ...]
    links: tuple[Link, ...] = ()
    meta: tuple[Meta, ...] = ()


Node = GroupNode | AccessNode | DataNode


@dataclass(frozen=True)
class RcmlDocument:
    """A valid RCML 2.0 document."""

    #: Where the robot's RCTP server listens (D-RCML-17).
    site: RctpUrl
    #: Top-level groups and access nodes, canonical order.
    children: tuple[GroupNode | AccessNode, ...]
    time_source: str = "local"
    time_precision: float | None = None
    title: str | None = None
    author: str | None = None
    info: str | None = None
    contact: str | None = None
    links: tuple[Link, ...] = ()
    meta: tuple[Meta, ...] = ()
    #: Every node by path (D-RCML-3), in document order: the loader adds each node as it meets
    #: it (the data nodes of an access before the access), the one place that order is kept.
    nodes: Mapping[str, Node] = field(default_factory=dict, compare=False, repr=False)

    def node(self, path: str) -> Node | None:
        return self.nodes.get(path)

    def children_of(self, path: str) -> tuple[Node, ...]:
        """The nodes directly below `path` (`/` or "" for the top of the tree)."""
        if path in ("", "/"):
            return self.children
        node = self.nodes.get(path)
        if isinstance(node, GroupNode):
            return node.children
        if isinstance(node, AccessNode):
            return node.data
        return ()

    def in_document_order(self, nodes: Iterable[DataNode]) -> tuple[DataNode, ...]:
        """Data nodes in the order their elements stand in the document. Nothing on the wire
        follows that order (D-RCML-4); it tells an implementation that does (R-RCML-29)."""
        order = {path: index for index, path in enumerate(self.nodes)}
        return tuple(sorted(nodes, key=lambda node: order[node.path]))

    def data_nodes(self) -> Iterator[DataNode]:
        return (n for n in self.nodes.values() if isinstance(n, DataNode))

    def access_nodes(self) -> Iterator[AccessNode]:
        return (n for n in self.nodes.values() if isinstance(n, AccessNode))
