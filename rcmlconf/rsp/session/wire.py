"""One side of one session on the wire: numbering, stamps, the replay window and sealing.

Both endpoints use it the same way: `build` makes a packet (sequence number, timestamp and last
received sequence number filled in, R-RSP-14, R-RSP-15; sealed in an encrypted session,
D-RSP-21) and `read` takes one, or raises `ProtocolError` with the R-RSP-18 reason to drop it for.
Nothing a packet says moves the replay window before the packet proved authentic.
"""

from __future__ import annotations

from rcmlconf.errors import ProtocolError
from rcmlconf.hotpath import make_namedtuple
from rcmlconf.rctp.datastream.order import Arrival, SequenceTracker
from rcmlconf.rsp.codec import Encryption, Header, Packet, PacketType, RspCodec
from rcmlconf.rsp.codec.bodies import Body
from rcmlconf.rsp.codec.header import SEQUENCE_AT, SESSION_AT, TYPE_AT, WITHOUT_SESSION
from rcmlconf.rsp.layout import HEADER_SIZE, MAC_SIZE
from rcmlconf.rsp.security import Direction, Sealer, mac, mac_matches, session_key
from rcmlconf.wording import indefinite

DROP = "R-RSP-18"
#: D-RSP-11: the packet types each side is sent; any other is malformed to it (R-RSP-18).
SENT_TO_ROBOT = frozenset(
    {PacketType.HELLO, PacketType.DOWNLINK, PacketType.ACK, PacketType.PERIOD, PacketType.BYE}
)
SENT_TO_LOCAL = frozenset(
    {PacketType.WELCOME, PacketType.REFUSED, PacketType.UPLINK, PacketType.ACK, PacketType.BYE}
)
#: D-RSP-15: a packet further behind the newest than this is dropped unread.
REPLAY_WINDOW = 64
#: Sent in the clear with a MAC in an encrypted session: there is no key yet (D-RSP-21).
SIGNED = frozenset({PacketType.HELLO, PacketType.WELCOME})
_STAMP = 1 << 32
_SEQUENCE = 1 << 16


def drop_unsent(data: bytes, sent: frozenset[PacketType], receiver: str) -> None:
    """Raise the R-RSP-18 ProtocolError for a packet of a type `receiver` is not sent, before
    anything of it is read: it restores no link, moves no window, gives no buffer count. A type
    no packet has is left to the codec, which calls it malformed."""
    if len(data) > TYPE_AT and data[TYPE_AT] in _KNOWN:
        kind = PacketType(data[TYPE_AT])
        if kind not in sent:
            raise ProtocolError(f"{indefinite(kind.name)} is not sent to {receiver}", TYPE_AT, DROP)


_KNOWN = frozenset(int(kind) for kind in PacketType)


class SessionWire:
    """Packets of one session, as one side sends and receives them."""

    __slots__ = (
        "_epoch",
        "_model_id",
        "_opener",
        "_sealer",
        "_sends",
        "codec",
        "encryption",
        "sent",
        "session_id",
        "tracker",
    )

    def __init__(self, codec: RspCodec, encryption: Encryption, sends: Direction) -> None:
        self.codec = codec
        self.encryption = encryption
        self.session_id = 0
        self._model_id = codec.model.model_id
        self._sends = sends
        #: Packets sent: the packet index of D-RSP-21 (its low 16 bits are the sequence number).
        self.sent = 0
        self._epoch: float | None = None
        self.tracker = SequenceTracker()
        self._sealer: Sealer | None = None
        self._opener: Sealer | None = None

    def secure(self, psk: bytes, client_nonce: bytes, robot_nonce: bytes) -> None:
        """The session's keys, once its ID and both nonces are known (D-RSP-21)."""
        if self.encryption is Encryption.NONE:
            return
        receives = Direction.UPLINK if self._sends is Direction.DOWNLINK else Direction.DOWNLINK
        keys = {
            direction: session_key(psk, client_nonce, robot_nonce, self.session_id, direction)
            for direction in Direction
        }
        self._sealer = Sealer(self.encryption, keys[self._sends])
        self._opener = Sealer(self.encryption, keys[receives])

    def build(
        self, kind: PacketType, body: Body, now: float, buffer: int = 0, psk: bytes | None = None
    ) -> bytes:
        """The next packet; `psk` signs a HELLO or WELCOME of an encrypted session."""
        epoch = self._epoch
        if epoch is None:
            epoch = self._epoch = now
        index = self.sent
        self.sent = index + 1
        header = make_namedtuple(
            Header,
            (
                1,
                self._model_id,
                self.encryption,
                kind,
                index % _SEQUENCE,
                round((now - epoch) * 1000) % _STAMP,
                0 if kind in WITHOUT_SESSION else self.session_id,
                self.tracker.highest or 0,
                buffer,
            ),
        )
        data = self.codec.push_parts(header, body)
        # The encryption first: in a session without (most), no type is looked up (D-RSP-21).
        if self.encryption is not Encryption.NONE and kind in SIGNED:
            assert psk is not None, "an encrypted session signs its HELLO and WELCOME"
            unsigned = data[:-MAC_SIZE]
            return unsigned + mac(psk, unsigned)
        if self._sealer is None:
            return data
        return data[:HEADER_SIZE] + self._sealer.seal(data[:HEADER_SIZE], data[HEADER_SIZE:], index)

    def read(self, data: bytes, psk: bytes | None = None) -> tuple[Packet, Arrival]:
        """A packet of this session and how it arrived; ProtocolError when it is to be dropped."""
        if type(data) is not bytes:
            data = bytes(data)
        header = self.codec.pull_header(data)
        if header.session_id != self.session_id:
            raise ProtocolError("a packet of another session", SESSION_AT, DROP)
        if header.encryption is not self.encryption:
            raise ProtocolError(
                f"encryption {header.encryption.name}, not the session's {self.encryption.name}",
                3,
                DROP,
            )
        if self.tracker.replayed(header.sequence, REPLAY_WINDOW):
            raise ProtocolError("seen before, or more than 64 behind the newest", SEQUENCE_AT, DROP)
        body = self._body(header, data, psk)
        return make_namedtuple(Packet, (header, body)), self.tracker.see(header.sequence)

    def _body(self, header: Header, data: bytes, psk: bytes | None) -> Body:
        if self.encryption is not Encryption.NONE and header.type in SIGNED:
            if psk is None or not mac_matches(psk, data[:-MAC_SIZE], data[-MAC_SIZE:]):
                raise ProtocolError("the MAC is wrong", max(len(data) - MAC_SIZE, 0), "R-RSP-38")
        elif self._opener is not None:
            index = self.tracker.extended(header.sequence)
            plain = self._opener.open(data[:HEADER_SIZE], data[HEADER_SIZE:], index)
            return self.codec.pull_body(header, plain)
        return self.codec.pull_rest(header, data)
