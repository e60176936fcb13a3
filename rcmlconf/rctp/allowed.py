"""What each kind of target allows (D-RCTP-26): the node check of D-RCTP-25, as data.

A server answers a method outside its target's row with 405 and the row as `Allow` (R-RCTP-26);
the conformance harness and the dissector read the same table to know what a target takes.
"""

from __future__ import annotations

import enum

from rcmlconf.rcml.model import AccessNode, AccessType, DataNode, GroupNode, RcmlDocument
from rcmlconf.rctp.targets import ROOT, STAR


class TargetKind(enum.Enum):
    SESSION = "the session (*)"
    TREE = "a group, a normal access or the whole tree"
    NORMAL_DATA = "a data node of a normal access"
    EVENT_ACCESS = "an event access"
    STREAM_ACCESS = "a stream access"
    INNER_DATA = "a data node of an event or stream access"


_BOTH = ("ACQUIRE", "RELEASE")
_SET_UP = ("SETUP", "GO", "PAUSE", "STOP")

#: D-RCTP-26, in the table's order (the order of `Allow`).
ALLOWED: dict[TargetKind, tuple[str, ...]] = {
    TargetKind.SESSION: ("RELEASE", "BYE"),
    TargetKind.TREE: _BOTH,
    TargetKind.NORMAL_DATA: (*_BOTH, "READ", "WRITE"),
    TargetKind.EVENT_ACCESS: (*_BOTH, "READ", "WRITE", *_SET_UP),
    TargetKind.STREAM_ACCESS: (*_BOTH, *_SET_UP),
    TargetKind.INNER_DATA: _BOTH,
}

_ACCESS_KINDS = {
    AccessType.NORMAL: TargetKind.TREE,
    AccessType.EVENT: TargetKind.EVENT_ACCESS,
    AccessType.STREAM: TargetKind.STREAM_ACCESS,
}


def target_kind(model: RcmlDocument, path: str) -> TargetKind | None:
    """The kind of a decoded target (`Target.path`); None when it names no node (404)."""
    if path == STAR:
        return TargetKind.SESSION
    if path == ROOT:
        return TargetKind.TREE
    node = model.node(path)
    if isinstance(node, GroupNode):
        return TargetKind.TREE
    if isinstance(node, AccessNode):
        return _ACCESS_KINDS[node.type]
    if isinstance(node, DataNode):
        parent = model.node(path.rsplit("/", 1)[0])
        assert isinstance(parent, AccessNode)  # data nodes live in access nodes (D-RCML-2)
        normal = parent.type is AccessType.NORMAL
        return TargetKind.NORMAL_DATA if normal else TargetKind.INNER_DATA
    return None
