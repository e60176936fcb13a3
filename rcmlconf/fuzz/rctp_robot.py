"""What an RCTP/2.0 server's robot offers a fuzzer: its paths by kind, and valid bodies.

The fuzzer reaches states (D-FUZZ-2) through real nodes of the robot's RCML, and mutates
messages that would be valid there. Everything comes from the document; nothing is guessed.
"""

from __future__ import annotations

from dataclasses import dataclass

from rcmlconf.rcml.model import AccessNode, AccessType, DataNode, Permission, RcmlDocument
from rcmlconf.rctp.bodies import ValuesCodec
from rcmlconf.rctp.datastream.flow import Direction
from rcmlconf.rctp.datastream.values import stream_codec


@dataclass(frozen=True, slots=True)
class RobotPaths:
    """The robot's paths the fuzzer uses, each None when the robot has none of that kind."""

    site: str
    #: A data node of a normal access that can be read, and one that can be written.
    readable: DataNode | None
    writable: DataNode | None
    #: A stream access, and whether it has writable nodes (mode both, ACQUIRE first).
    stream: AccessNode | None
    #: An event access (SETUP, GO, and the server's data-change WRITEs, D-RCTP-27).
    event: AccessNode | None
    #: Every path of the tree, for targets that name other nodes.
    paths: tuple[str, ...]

    @property
    def stream_writes(self) -> bool:
        return self.stream is not None and bool(self.stream.writable())

    def zero_body(self, node: DataNode) -> bytes:
        """A WRITE body holding the node's zero value (D-RCTP-8)."""
        return ValuesCodec([node], node.path, "R-RCTP-6").encode({node.name: node.zero()})

    def stream_body(self) -> bytes | None:
        """A DATA body of the stream's writable nodes, each its zero value (D-RCTP-20)."""
        if self.stream is None or not self.stream.writable():
            return None
        codec = stream_codec(self.stream, Direction.WRITE)
        return codec.encode({node.name: node.zero() for node in codec.nodes})


def robot_paths(robot: RcmlDocument, site: str | None = None) -> RobotPaths:
    accesses = list(robot.access_nodes())
    normal = [a for a in accesses if a.type is AccessType.NORMAL]
    data = [d for a in normal for d in a.data]
    streams = [a for a in accesses if a.type is AccessType.STREAM]
    # A stream with writable nodes reaches the most code: the privilege, both directions.
    streams.sort(key=lambda a: not a.writable())
    return RobotPaths(
        site=site or robot.site.path or "/",
        readable=next((d for d in data if Permission.READ in d.permission), None),
        writable=next((d for d in data if Permission.WRITE in d.permission), None),
        stream=streams[0] if streams else None,
        event=next((a for a in accesses if a.type is AccessType.EVENT), None),
        paths=tuple(robot.nodes),
    )
