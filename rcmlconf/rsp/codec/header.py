"""The 20-byte header of every RSP packet (D-RSP-10) and the packet types it names (D-RSP-11).

`pull_header` and `push_header` check what holds for any model: version 1 (R-RSP-13), a model ID
from 1 to 65,535 (D-RSP-6: 0 names none), a known encryption and type, a session ID that is 0
exactly in HELLO and REFUSED, and a buffer byte of the form its sender gives it. `HeaderRules` also
holds a model's own rules — its model ID, its `commandBuffers` — so that a codec made for one model
refuses the packets of another. Both check every field with one expression and ask `fault`, field
by field, only for the reason and offset of a header they refuse.

`Header` is a NamedTuple, not a frozen dataclass: one is made for every packet a session sends or
receives (every T, D-RSP-13), and a frozen dataclass of nine fields costs seven times as much to
make (bench/rsp_codec_speed.py).
"""

from __future__ import annotations

import enum
import struct
from collections.abc import Container
from typing import NamedTuple

from rcmlconf.errors import EncodeError, ProtocolError
from rcmlconf.hotpath import make_namedtuple
from rcmlconf.rsp.model import MAX_MODEL_ID, RobotModel

RULE = "R-RSP-13"
VERSION = 1
#: D-RSP-10: the buffer byte of the local system; bits 0 to 6 are 0.
CLEAR_BUFFER = 0x80
#: The robot's free buffers fit in bits 0 to 6 (`commandBuffers` is at most 127, D-RSP-6).
MAX_FREE_BUFFERS = 0x7F
#: version, model ID, encryption, type, sequence number, timestamp, the session ID's high 16 and
#: low 32 bits, last received sequence number, buffer.
HEADER = struct.Struct(">BHBBHIHIHB")
#: Where each field of `HEADER` starts: what a fault is reported at, and what those who patch a
#: packet's bytes (the conformance cases' malformed packets, a flood's spoofed ones) patch.
VERSION_AT, MODEL_AT, ENCRYPTION_AT, TYPE_AT, SEQUENCE_AT = 0, 1, 3, 4, 5
TIMESTAMP_AT, SESSION_AT, LAST_AT, BUFFER_AT = 7, 11, 17, 19
_unpack_from = HEADER.unpack_from
_pack = HEADER.pack


class PacketType(enum.IntEnum):
    """D-RSP-11. Other types are malformed."""

    HELLO = 1
    WELCOME = 2
    REFUSED = 3
    DOWNLINK = 4
    UPLINK = 5
    ACK = 6
    BYE = 7
    PERIOD = 8


class Encryption(enum.IntEnum):
    """The header's encryption byte (D-RSP-10, D-RSP-21)."""

    NONE = 0
    AES_256_GCM = 1
    CHACHA20_POLY1305 = 2


class Sender(enum.Enum):
    """Who sends a packet type (D-RSP-11): it decides the form of the buffer byte."""

    LOCAL = "local"
    ROBOT = "robot"
    EITHER = "either"


SENDERS: dict[PacketType, Sender] = {
    PacketType.HELLO: Sender.LOCAL,
    PacketType.WELCOME: Sender.ROBOT,
    PacketType.REFUSED: Sender.ROBOT,
    PacketType.DOWNLINK: Sender.LOCAL,
    PacketType.UPLINK: Sender.ROBOT,
    PacketType.ACK: Sender.EITHER,
    PacketType.BYE: Sender.EITHER,
    PacketType.PERIOD: Sender.LOCAL,
}
#: D-RSP-10: "session ID ... 0 only in HELLO and REFUSED".
WITHOUT_SESSION = frozenset({PacketType.HELLO, PacketType.REFUSED})
#: Wire values to members, so that decoding a byte is a dict lookup and an unknown one is None.
_TYPES = {int(member): member for member in PacketType}
_ENCRYPTIONS = {int(member): member for member in Encryption}


class Header(NamedTuple):
    """The nine fields of Table II, in their order (D-RSP-10)."""

    version: int
    model_id: int
    encryption: Encryption
    type: PacketType
    #: Per sender per session, modulo 65,536 (R-RSP-14).
    sequence: int
    #: Milliseconds since the sender's first packet of the session, modulo 2^32 (R-RSP-14).
    timestamp: int
    #: 48 bits; 0 only in HELLO and REFUSED.
    session_id: int
    #: The newest sequence number received from the peer (R-RSP-15).
    last_received: int
    #: From the local system CLEAR_BUFFER or 0; from the robot its free memory-command buffers.
    buffer: int


class _AnyModel:
    """The model IDs of any model: 1 to 65,535 (D-RSP-6)."""

    def __contains__(self, model_id: object) -> bool:
        return isinstance(model_id, int) and 1 <= model_id <= MAX_MODEL_ID


_ANY_MODEL = _AnyModel()


class HeaderRules:
    """What a header must hold, for any model (`ANY`) or for one (`for_model`)."""

    __slots__ = ("_buffers", "_by_type", "_highest", "_lowest", "_model_ids", "model_id")

    def __init__(self, model_id: int | None, command_buffers: int) -> None:
        self.model_id = model_id
        #: D-RSP-6: a model's ID, or any model's (1 to 65,535: 0 names none).
        self._model_ids: Container[object] = (
            _ANY_MODEL if model_id is None else frozenset({model_id})
        )
        #: The same as the bounds `pull` compares the ints it unpacks with (a comparison costs a
        #: tenth of `_AnyModel`'s call).
        self._lowest, self._highest = (1, MAX_MODEL_ID) if model_id is None else (model_id,) * 2
        robot = frozenset(range(command_buffers + 1))
        local = frozenset({0, CLEAR_BUFFER})
        #: D-RSP-10: the buffer byte each sender may give.
        self._buffers = {Sender.LOCAL: local, Sender.ROBOT: robot, Sender.EITHER: local | robot}
        #: Wire type -> (member, whether its session ID is 0, the buffer bytes its sender gives):
        #: what `fault` checks field by field, as one lookup for `pull` and `push`.
        self._by_type = {
            int(kind): (kind, kind in WITHOUT_SESSION, self._buffers[sender])
            for kind, sender in SENDERS.items()
        }

    @classmethod
    def for_model(cls, model: RobotModel) -> HeaderRules:
        return cls(model.model_id, model.command_buffers)

    def fault(self, header: Header) -> tuple[str, int] | None:
        """Why the header breaks R-RSP-13, and the offset of the field at fault; None if it holds.

        Fields are checked in their order, so the first fault in the bytes is the one reported.
        `pull` and `push` check the same with one expression and ask here only for the reason.
        """
        if header.version != VERSION:
            return f"version {header.version}, not {VERSION}", VERSION_AT
        if header.model_id not in self._model_ids:
            if self.model_id is None:
                return f"model ID {header.model_id} is no model's (1 to {MAX_MODEL_ID})", MODEL_AT
            return f"model ID {header.model_id}, not this model's {self.model_id}", MODEL_AT
        if header.encryption not in _ENCRYPTIONS:
            return (
                f"encryption {header.encryption} is none of {sorted(_ENCRYPTIONS)}",
                ENCRYPTION_AT,
            )
        sender = SENDERS.get(header.type)
        if sender is None:
            return f"packet type {header.type} is none of 1 to {len(SENDERS)}", TYPE_AT
        name = _TYPES[header.type].name
        if (header.session_id == 0) != (header.type in WITHOUT_SESSION):
            if header.type in WITHOUT_SESSION:
                return f"the session ID of {name} is 0, not {header.session_id}", SESSION_AT
            return f"the session ID of {name} is never 0", SESSION_AT
        if header.buffer not in self._buffers[sender]:
            return f"buffer byte 0x{header.buffer:02x} is not one {name}'s sender gives", BUFFER_AT
        return None

    def pull(self, data: bytes | bytearray | memoryview) -> Header:
        """The header at the start of a datagram."""
        try:
            version, model_id, encryption, kind, sequence, timestamp, high, low, last, buffer = (
                _unpack_from(data)
            )
        except struct.error:
            # The version first: a packet of another version may have another layout, so it is
            # reported as that rather than as cut short.
            size = len(data)
            if size and data[0] != VERSION:
                raise ProtocolError(f"version {data[0]}, not {VERSION}", 0, RULE) from None
            raise ProtocolError(f"header of {size} bytes, not {HEADER.size}", size, RULE) from None
        rules = self._by_type.get(kind)
        enum = _ENCRYPTIONS.get(encryption)
        if (
            version == VERSION
            and self._lowest <= model_id <= self._highest
            and enum is not None
            and rules is not None
            and (not (high or low)) is rules[1]
            and buffer in rules[2]
        ):
            return make_namedtuple(
                Header,
                (
                    version,
                    model_id,
                    enum,
                    rules[0],
                    sequence,
                    timestamp,
                    high << 32 | low,
                    last,
                    buffer,
                ),
            )
        header = Header(
            version,
            model_id,
            _ENCRYPTIONS.get(encryption, encryption),
            _TYPES.get(kind, kind),
            sequence,
            timestamp,
            high << 32 | low,
            last,
            buffer,
        )
        fault = self.fault(header)
        if fault is None:  # the two checks are the same: this does not happen
            return header
        raise ProtocolError(*fault, RULE)

    def push(self, header: Header) -> bytes:
        """The header's 20 bytes; EncodeError for a header `pull` would refuse."""
        try:
            version, model_id, encryption, kind, sequence, timestamp, session, last, buffer = header
            rules = self._by_type.get(kind)
            if (
                version == VERSION
                and model_id in self._model_ids
                and encryption in _ENCRYPTIONS
                and rules is not None
                and (session == 0) is rules[1]
                and buffer in rules[2]
            ):
                return _pack(
                    version,
                    model_id,
                    encryption,
                    kind,
                    sequence,
                    timestamp,
                    session >> 32,
                    session & 0xFFFFFFFF,
                    last,
                    buffer,
                )
            fault = self.fault(header)
        except (struct.error, TypeError, ValueError) as exc:
            raise EncodeError(f"a header field does not fit: {exc}") from None
        raise EncodeError(f"header: {fault[0] if fault else 'not a header'}")


#: The rules every model shares.
ANY = HeaderRules(None, MAX_FREE_BUFFERS)


def pull_header(data: bytes | bytearray | memoryview) -> Header:
    """The header of a datagram of any model (R-RSP-13); `RspCodec.pull_header` checks its model."""
    return ANY.pull(data)


def push_header(header: Header) -> bytes:
    return ANY.push(header)
