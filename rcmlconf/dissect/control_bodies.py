"""The values of a READ's answer or a WRITE's body, decoded with the robot's RCML (D-RCTP-8)."""

from __future__ import annotations

from rcmlconf.errors import ProtocolError, ValueTextError
from rcmlconf.rcml.model import AccessNode, DataNode, RcmlDocument
from rcmlconf.rctp.bodies import ValuesCodec
from rcmlconf.rctp.fields import parse_nodes
from rcmlconf.rctp.targets import parse_target
from rcmlconf.values import Value


def body_values(
    rcml: RcmlDocument | None, target: str, nodes: str | None, body: bytes
) -> dict[str, Value] | None:
    """A body's values (D-RCTP-8): of the data node the target names, or of the `Nodes` of
    the event access it names (D-RCTP-17); None without the RCML, or when they do not
    decode (the answer to that is the server's: 422, R-RCTP-28)."""
    if rcml is None:
        return None
    try:
        path = parse_target(target).path
    except ValueTextError:
        return None
    node = rcml.node(path)
    if isinstance(node, DataNode):
        chosen: tuple[DataNode, ...] = (node,)
    elif isinstance(node, AccessNode) and nodes is not None:
        by_name = {data.name: data for data in node.data}
        try:
            names = parse_nodes(nodes)
        except ValueTextError:
            return None
        if not all(name in by_name for name in names):
            return None
        chosen = tuple(by_name[name] for name in names)
    else:
        return None
    try:
        return ValuesCodec(chosen, path, "R-RCTP-28").decode(body)
    except ProtocolError:
        return None
