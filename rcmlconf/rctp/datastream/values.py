"""DATA payload bodies (D-RCTP-20): the values of a stream access's data nodes for one direction.

Readable nodes travel robot to client (direction read), writable ones client to robot (write), in
canonical order (D-RCML-4) in the binary value format (D-RCML-10), with nothing before, between or
after them (R-RCTP-40). One `ValuesCodec` per access and direction holds the nodes' codecs, so a
stream's packets do not look them up again.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

from rcmlconf.buffer import Buffer
from rcmlconf.errors import EncodeError, ProtocolError
from rcmlconf.rcml.model import AccessNode, DataNode
from rcmlconf.rctp.datastream.flow import Direction
from rcmlconf.values import Value
from rcmlconf.values.binary import Puller, Pusher, codec_for

_RULE = "R-RCTP-40"

#: Which of an access's data nodes travel in each direction, already in canonical order.
_NODES: dict[Direction, Callable[[AccessNode], tuple[DataNode, ...]]] = {
    Direction.READ: AccessNode.readable,
    Direction.WRITE: AccessNode.writable,
}


class ValuesCodec:
    """Encode and decode the DATA bodies of one access in one direction."""

    __slots__ = ("_codecs", "access", "direction", "names")

    def __init__(self, access: AccessNode, direction: Direction) -> None:
        self.access = access
        self.direction = direction
        nodes = _NODES[direction](access)
        #: The data nodes' names in the order their values travel.
        self.names = tuple(node.name for node in nodes)
        self._codecs: tuple[tuple[str, Puller, Pusher], ...] = tuple(
            (node.name, *codec_for(node.type)) for node in nodes
        )

    def encode(self, values: Mapping[str, Value]) -> bytes:
        """A body from a value for each node of the direction, no more and no fewer."""
        if values.keys() != set(self.names):
            missing = sorted(set(self.names) - values.keys())
            extra = sorted(values.keys() - set(self.names))
            raise EncodeError(
                f"{self.access.path} ({self.direction.name.lower()}) needs a value for each of"
                f" {list(self.names)} and no other: missing {missing}, unknown {extra}"
            )
        buf = Buffer()
        for name, _, push in self._codecs:
            try:
                push(buf, values[name])
            except EncodeError as exc:
                raise EncodeError(f"{self.access.path}/{name}: {exc}") from None
        return buf.data()

    def decode(self, body: bytes, base: int = 0) -> dict[str, Value]:
        """The values of a body. `base` is where the body starts in its datagram
        (`packets.body_offsets`), so that an error's offset counts from the datagram's start.
        """
        buf = Buffer(body)
        try:
            values = {name: pull(buf) for name, pull, _ in self._codecs}
        except ProtocolError as exc:
            # A value cut short breaks R-RCTP-40 (the body does not hold the values); a value
            # that is itself malformed keeps the rule it breaks (R-RCML-30).
            raise ProtocolError(exc.reason, base + exc.offset, exc.rule or _RULE) from None
        if not buf.eof():
            raise ProtocolError(
                f"{buf.remaining} bytes after the values of {self.access.path}",
                base + buf.position,
                _RULE,
            )
        return values
