"""Bodies of values (D-RCTP-8, D-RCTP-20): the values of a list of data nodes, back to back.

READ and WRITE carry the values of the nodes they name (one node of a normal access, or the
`Nodes` of an event access, D-RCTP-17); a DATA payload carries those of a stream access for one
direction (D-RCTP-20). Both are the same thing: the binary value format (D-RCML-10) of each node
in canonical order (D-RCML-4), nothing before, between or after. One `ValuesCodec` holds the
nodes' codecs, so a stream's packets do not look them up again.

RSP payloads are the same format in another order: a device's fields in document order (D-RSP-4),
each payload one run of values among others in a packet (`pull`, `push`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Generic, TypeVar

from rcmlconf.buffer import Buffer
from rcmlconf.errors import EncodeError, ProtocolError
from rcmlconf.values import Value
from rcmlconf.values.binary import Puller, Pusher, codec_for
from rcmlconf.values.shown import Typed

__all__ = ["Node", "Typed", "ValuesCodec"]

Node = TypeVar("Node", bound=Typed)


class ValuesCodec(Generic[Node]):
    """Encode and decode the bodies that hold a value for each of some data nodes."""

    __slots__ = ("_codecs", "names", "nodes", "rule", "where")

    def __init__(
        self, nodes: Sequence[Node], where: str, rule: str, *, canonical: bool = True
    ) -> None:
        #: The nodes, in the order their values travel: canonical order (D-RCML-4), or the order
        #: given when `canonical` is false (an RSP device's fields, D-RSP-4).
        self.nodes = tuple(sorted(nodes, key=lambda node: node.name) if canonical else nodes)
        self.names = tuple(node.name for node in self.nodes)
        #: What the body belongs to, for messages (`/drive/wheels (read)`).
        self.where = where
        #: The requirement a body that does not hold exactly these values breaks.
        self.rule = rule
        self._codecs: tuple[tuple[str, Puller, Pusher], ...] = tuple(
            (node.name, *codec_for(node.type)) for node in self.nodes
        )

    def encode(self, values: Mapping[str, Value]) -> bytes:
        """A body from a value for each node, no more and no fewer."""
        buf = Buffer()
        self.push(buf, values)
        return buf.data()

    def push(self, buf: Buffer, values: Mapping[str, Value]) -> None:
        """Append the values, as `encode` does."""
        if values.keys() != set(self.names):
            missing = sorted(set(self.names) - values.keys())
            extra = sorted(values.keys() - set(self.names))
            raise EncodeError(
                f"{self.where} needs a value for each of {list(self.names)} and no other:"
                f" missing {missing}, unknown {extra}"
            )
        for name, _, push in self._codecs:
            try:
                push(buf, values[name])
            except EncodeError as exc:
                raise EncodeError(f"{self.where}/{name}: {exc}") from None

    def decode(self, body: bytes, base: int = 0) -> dict[str, Value]:
        """The values of a body. `base` is where the body starts in its message or datagram, so
        that an error's offset counts from there.
        """
        buf = Buffer(body)
        try:
            values = self.pull(buf)
        except ProtocolError as exc:
            raise ProtocolError(exc.reason, base + exc.offset, exc.rule) from None
        if not buf.eof():
            raise ProtocolError(
                f"{buf.remaining} bytes after the values of {self.where}",
                base + buf.position,
                self.rule,
            )
        return values

    def pull(self, buf: Buffer) -> dict[str, Value]:
        """The values at the buffer's position; offsets in errors are the buffer's."""
        try:
            return {name: pull(buf) for name, pull, _ in self._codecs}
        except ProtocolError as exc:
            # A value cut short breaks this body's rule (the body does not hold the values); a
            # value that is itself malformed keeps the rule it breaks (R-RCML-30).
            if exc.rule:
                raise
            raise ProtocolError(exc.reason, exc.offset, self.rule) from None
