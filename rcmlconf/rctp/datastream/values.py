"""DATA payload bodies (D-RCTP-20): the values of a stream access's data nodes for one direction.

Readable nodes travel robot to client (direction read), writable ones client to robot (write), in
canonical order (D-RCML-4) in the binary value format (D-RCML-10), with nothing before, between or
after them (R-RCTP-40). The body is the same as a READ's or WRITE's (`rctp.bodies`); only which
nodes it holds is the stream's own.
"""

from __future__ import annotations

from collections.abc import Callable

from rcmlconf.rcml.model import AccessNode, DataNode
from rcmlconf.rctp.bodies import ValuesCodec
from rcmlconf.rctp.datastream.flow import Direction

#: Which of an access's data nodes travel in each direction.
_NODES: dict[Direction, Callable[[AccessNode], tuple[DataNode, ...]]] = {
    Direction.READ: AccessNode.readable,
    Direction.WRITE: AccessNode.writable,
}


def stream_codec(access: AccessNode, direction: Direction) -> ValuesCodec[DataNode]:
    """The codec of the DATA bodies of one stream access in one direction."""
    where = f"{access.path} ({direction.name.lower()})"
    return ValuesCodec(_NODES[direction](access), where, "R-RCTP-40")
