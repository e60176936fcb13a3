"""Whole RSP packets of one robot model: header and body, as plaintext (D-RSP-10, D-RSP-11).

`RspCodec` is derived from the model at run time: no per-robot code. The endpoints of one model in
a process share one (`codec_for`). An encrypted session seals and opens bodies around it
(`rsp.security`): it reads the header with `pull_header`, opens what follows, and reads that with
`pull_body`; an unencrypted one reads the body in place with `pull_rest`.
"""

from __future__ import annotations

from functools import lru_cache

from rcmlconf.buffer import Buffer
from rcmlconf.errors import EncodeError, ProtocolError
from rcmlconf.hotpath import make_namedtuple
from rcmlconf.rsp.codec.bodies import (
    BODIES,
    Body,
    Item,
    MapBody,
    Packet,
    _new_body,
    _set_items,
    pull_session_body,
    push_session_body,
)
from rcmlconf.rsp.codec.header import RULE, Header, HeaderRules, PacketType
from rcmlconf.rsp.codec.maps import MapCodec
from rcmlconf.rsp.layout import HEADER_SIZE, MapPacket
from rcmlconf.rsp.model import RobotModel

_MAP_PACKETS = {
    PacketType.DOWNLINK: MapPacket.DOWNLINK,
    PacketType.UPLINK: MapPacket.UPLINK,
    PacketType.ACK: MapPacket.ACK,
}


class RspCodec:
    """Read and write the packets of one model; the only exception a read lets escape is
    `ProtocolError` (offset, reason, rule), a write's is `EncodeError`."""

    __slots__ = ("_maps", "_maps_by_type", "model", "rules")

    def __init__(self, model: RobotModel) -> None:
        self.model = model
        self.rules = HeaderRules.for_model(model)
        self._maps = {kind: MapCodec(model, packet) for kind, packet in _MAP_PACKETS.items()}
        #: The same, indexed by the wire type (0 to 8): for a header `rules` has checked, whose
        #: type is one of 1 to 8, an index costs less than a dict lookup.
        by_type: list[MapCodec | None] = [None] * (max(PacketType) + 1)
        for kind, codec in self._maps.items():
            by_type[kind] = codec
        self._maps_by_type = tuple(by_type)

    def pull_header(self, data: bytes | bytearray | memoryview) -> Header:
        """The header of a datagram, checked against this model (R-RSP-13)."""
        return self.rules.pull(data)

    def push_header(self, header: Header) -> bytes:
        return self.rules.push(header)

    def pull_body(
        self, header: Header, body: bytes | bytearray | memoryview, base: int = HEADER_SIZE
    ) -> Body:
        """The body of a packet of that header; `base` is where it starts, for offsets."""
        if header.type not in BODIES:
            raise ProtocolError(f"packet type {header.type} is none of 1 to {len(BODIES)}", 4, RULE)
        data = bytes(body)
        try:
            return self._pull_body(header, data, 0)
        except ProtocolError as exc:
            raise ProtocolError(exc.reason, base + exc.offset, exc.rule) from None

    def _pull_body(self, header: Header, data: bytes, start: int) -> Body:
        """The body from `start` to the end of `data`; offsets are `data`'s. The header's type is
        one of D-RSP-11's (`pull` or `pull_body` checked it)."""
        maps = self._maps_by_type[header[3]]
        if maps is not None:
            # `map_body`, inline: one is made for every map packet read.
            body = _new_body(MapBody)
            _set_items(body, maps.pull_from(data, start))
            return body
        cls = BODIES[header.type]
        assert cls is not MapBody
        try:
            return pull_session_body(cls, header, Buffer(memoryview(data)[start:]))  # type: ignore[arg-type]
        except ProtocolError as exc:
            raise ProtocolError(exc.reason, start + exc.offset, exc.rule) from None

    def push_body(self, header: Header, body: Body) -> bytes:
        try:
            cls = BODIES[header.type]
        except (AttributeError, KeyError, TypeError):
            raise EncodeError(f"no packet type carries a body in {header!r}") from None
        if not isinstance(body, cls):
            raise EncodeError(
                f"a {PacketType(header.type).name} carries a {cls.__name__},"
                f" not a {type(body).__name__}"
            )
        if isinstance(body, MapBody):
            return self._maps[header.type].push(body.items)
        return push_session_body(header, body)

    def check_item(self, kind: PacketType, item: Item) -> None:
        """EncodeError unless a DOWNLINK, UPLINK or ACK (`kind`) can carry `item`."""
        self._maps[kind].check(item)

    def pull_packet(self, data: bytes | bytearray | memoryview) -> Packet:
        """A whole plaintext datagram."""
        if type(data) is not bytes:
            data = bytes(data)
        header = self.rules.pull(data)
        return make_namedtuple(Packet, (header, self.pull_rest(header, data)))

    def pull_rest(self, header: Header, data: bytes) -> Body:
        """The body of a whole plaintext datagram whose header `pull_header` gave: read in place,
        with the datagram's offsets (a session reads one every period, D-RSP-13)."""
        return self._pull_body(header, data, HEADER_SIZE)

    def push_packet(self, packet: Packet) -> bytes:
        try:
            header, body = packet
        except (TypeError, ValueError):
            raise EncodeError(f"a packet is a header and a body, not {packet!r}") from None
        return self.push_parts(header, body)

    def push_parts(self, header: Header, body: Body) -> bytes:
        """`push_packet` of a header and a body not yet made a `Packet`."""
        head = self.rules.push(header)
        maps = self._maps.get(header.type)
        if maps is not None and type(body) is MapBody:
            return head + maps.push(body.items)
        return head + self.push_body(header, body)


#: Models whose codec `codec_for` keeps: a process serves a few models, a test run makes many.
SHARED_MODELS = 64


@lru_cache(maxsize=SHARED_MODELS)
def codec_for(model: RobotModel) -> RspCodec:
    """The codec of a model (or of an equal one), shared by the endpoints of it in the process.

    Hundreds of sessions of one model in one process (bench/rsp_pairs_scale.py) each with a codec
    of their own — its slots, header rules, plans and compiled layouts, about 36 KB — touch
    that much more memory every period: at 150 pairs the caches missed for about 15 % of the
    time. A codec's state is caches only (plans, layouts, the map last read and written), so
    sharing it changes no outcome; sessions sending other maps share its bounded plans.
    """
    return RspCodec(model)
