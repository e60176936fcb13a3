"""What the RCTP server cases name in their requests: nodes picked from the robot's RCML by kind
and permission, never by name (a robot without the kind a case needs makes it not applicable),
and names no server knows."""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

from rcmlconf.conformance.context import Context
from rcmlconf.conformance.verdicts import NotApplicable
from rcmlconf.rcml.model import AccessNode, AccessType, DataNode, Permission
from rcmlconf.rctp.bodies import ValuesCodec
from rcmlconf.rctp.fields import format_nodes
from rcmlconf.rctp.targets import ROOT, format_target
from rcmlconf.values import Value

RW = Permission.READ | Permission.WRITE
#: A name no RCML node of a sane robot has; the cases check the model anyway.
MISSING = "rcmlconfNoSuchNode"
#: A session ID no server hands out, of the right form.
STRANGER = "rcmlconf-not-a-session"


@dataclass(frozen=True)
class Named:
    """The target of a READ or WRITE and the data nodes its body holds (D-RCTP-17): one data node
    of a normal access, or an event access with `Nodes`."""

    #: The decoded path of the target: the data node, or the event access.
    path: str
    #: Canonical order (D-RCML-4).
    nodes: tuple[DataNode, ...]
    event: bool

    @property
    def target(self) -> str:
        return format_target(self.path)

    @property
    def node(self) -> DataNode:
        return self.nodes[0]

    def fields(self) -> list[tuple[str, str]]:
        return [("Nodes", format_nodes([n.name for n in self.nodes]))] if self.event else []

    def codec(self, rule: str) -> ValuesCodec[DataNode]:
        return ValuesCodec(self.nodes, self.path, rule)

    def encode(self, values: Mapping[str, Value]) -> bytes:
        return self.codec("R-RCTP-28").encode(values)


def pick(
    ctx: Context,
    fits: Callable[[DataNode], bool],
    kinds: Sequence[AccessType] = (AccessType.NORMAL, AccessType.EVENT),
    what: str = "data node",
) -> Named:
    """One data node that `fits`, named as READ and WRITE name it: a data node of a normal
    access if the robot has one, else one of an event access (`kinds`, in that order)."""
    accesses = list(ctx.robot.access_nodes())
    for kind in kinds:
        for access in accesses:
            node = next((d for d in access.data if fits(d)), None)
            if access.type is kind and node is not None:
                if kind is AccessType.NORMAL:
                    return Named(node.path, (node,), event=False)
                return Named(access.path, (node,), event=True)
    where = " or ".join(k.value for k in kinds)
    raise NotApplicable(f"the robot has no {what} of a {where} access")


def writable(
    ctx: Context,
    fits: Callable[[DataNode], bool] = lambda node: True,
    what: str = "writable data node",
) -> Named:
    """A data node a WRITE may write that `fits`, as `pick` names it: one that can be read too
    where the robot has one, since only a node read before and after shows what a WRITE changed,
    or that a refused one changed nothing (R-RCTP-28)."""
    for needed in (RW, Permission.WRITE):

        def usable(node: DataNode, needed: Permission = needed) -> bool:
            return needed in node.permission and fits(node)

        with contextlib.suppress(NotApplicable):
            return pick(ctx, usable, what=what)
    raise NotApplicable(f"the robot has no {what} of a normal or event access")


def read_target(ctx: Context, *, encoded: bool = True) -> str:
    """What a READ names that needs no Nodes: a readable data node of a normal access, else a
    readable event access; its target, or (not `encoded`) its path."""
    try:
        path = ctx.data(AccessType.NORMAL, Permission.READ).path
    except NotApplicable:
        path = ctx.access(AccessType.EVENT, where=lambda access: bool(access.readable())).path
    return format_target(path) if encoded else path


def event_access(ctx: Context, fits: Callable[[AccessNode], bool], what: str) -> AccessNode:
    found = next(
        (a for a in ctx.robot.access_nodes() if a.type is AccessType.EVENT and fits(a)), None
    )
    if found is None:
        raise NotApplicable(f"the robot has no event access {what}")
    return found


def first(ctx: Context, kind: AccessType) -> AccessNode | None:
    """The robot's first access of `kind`, if it has one."""
    return next((a for a in ctx.robot.access_nodes() if a.type is kind), None)


def missing_path(ctx: Context) -> str:
    """A path below an existing access that names no node."""
    access = next(iter(ctx.robot.access_nodes()), None)
    base = access.path if access is not None else ""
    path = f"{base}/{MISSING}"
    if ctx.robot.node(path) is not None:
        raise NotApplicable(f"the robot has a node {path}")
    return path


def unknown_target(ctx: Context) -> str:
    """A path of one segment, an XML Name, that names no node of the robot."""
    path = f"/{MISSING}"
    while ctx.robot.node(path) is not None:
        path += "X"
    return path


def parent_of(path: str) -> str:
    return path.rsplit("/", 1)[0] or ROOT
