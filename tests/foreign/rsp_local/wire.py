"""RSP packets as the local system sees them (specs/rsp.md §2, §3, D-RSP-21)."""

from __future__ import annotations

import hashlib
import hmac
import struct
from dataclasses import dataclass
from typing import Any

import bugs
from rmodel import Malformed, Model

HEADER = struct.Struct(">BHBBHI6sHB")
HELLO, WELCOME, REFUSED, DOWNLINK, UPLINK, ACK, BYE, PERIOD = range(1, 9)
TYPE_NAMES = {
    1: "HELLO",
    2: "WELCOME",
    3: "REFUSED",
    4: "DOWNLINK",
    5: "UPLINK",
    6: "ACK",
    7: "BYE",
    8: "PERIOD",
}
BYE_CLOSED, BYE_TIMEOUT, BYE_SHUTDOWN = 0, 1, 2
NO_ENCRYPTION, AES_256_GCM, CHACHA20_POLY1305 = 0, 1, 2
TAG = 16


@dataclass
class Header:
    version: int
    model_id: int
    encryption: int
    type: int
    seq: int
    timestamp: int
    session: int
    last_received: int
    buffer: int

    def pack(self) -> bytes:
        return HEADER.pack(
            self.version,
            self.model_id,
            self.encryption,
            self.type,
            self.seq,
            self.timestamp,
            self.session.to_bytes(6, "big"),
            self.last_received,
            self.buffer,
        )

    @classmethod
    def unpack(cls, data: bytes) -> Header:
        if len(data) < HEADER.size:
            raise Malformed("shorter than the header")
        v, mid, enc, typ, seq, ts, sid, last, buf = HEADER.unpack_from(data)
        return cls(v, mid, enc, typ, seq, ts, int.from_bytes(sid, "big"), last, buf)


# --- Device Map bodies (D-RSP-14) -------------------------------------------------------------

# The kinds whose bit a packet type may carry, and whether a payload follows the bit.
DOWN_BITS = {
    "module": False,
    "effector": True,
    "sensor": False,
    "monitor": False,
    "command": True,
    "event": False,
    "memoryCommand": True,
    "memoryEvent": False,
}
UP_BITS = {"sensor": True, "monitor": True, "event": True, "memoryEvent": True}
ACK_BITS = ("command", "memoryCommand", "memoryEvent")


def encode_map(model: Model, items: dict[int, bytes]) -> bytes:
    """A Device Map with the bits of `items` (device index -> payload), then the payloads."""
    bits = bytearray(model.map_length)
    for index in items:
        bits[index // 8] |= 0x80 >> (index % 8)
    return bytes(bits) + b"".join(items[i] for i in sorted(items))


def _set_bits(model: Model, body: bytes) -> list[int]:
    n = model.map_length
    if len(body) < n:
        raise Malformed("shorter than the Device Map")
    found = []
    for index in range(n * 8):
        if body[index // 8] & (0x80 >> (index % 8)):
            if index >= len(model.devices):
                if bugs.on("map-padding-taken"):
                    continue  # the bug: padding bits are skipped, not refused
                raise Malformed(f"bit {index} past the last device")
            found.append(index)
    return found


@dataclass
class Item:
    device: int
    ident: int | None
    values: list[Any]


def decode_uplink(model: Model, body: bytes, lenient: frozenset[str] = frozenset()) -> list[Item]:
    """An UPLINK body: every set bit with its ID (occurrences) and field values."""
    items = []
    at = model.map_length
    for index in _set_bits(model, body):
        dev = model.devices[index]
        if dev.kind not in UP_BITS:
            raise Malformed(f"{dev.kind} bit {dev.name} in an UPLINK")
        ident = None
        if dev.kind in ("event", "memoryEvent"):
            ident, at = _read_id(model, body, at)
        values = []
        for f in dev.fields:
            value, at = f.decode(body, at, "bool" in lenient)
            values.append(value)
        items.append(Item(index, ident, values))
    if at != len(body) and "trailing" not in lenient:
        raise Malformed(f"{len(body) - at} bytes after the payloads")
    return items


def decode_ack(model: Model, body: bytes, lenient: frozenset[str] = frozenset()) -> list[Item]:
    items = []
    at = model.map_length
    for index in _set_bits(model, body):
        dev = model.devices[index]
        if dev.kind not in ACK_BITS:
            raise Malformed(f"{dev.kind} bit {dev.name} in an ACK")
        ident, at = _read_id(model, body, at)
        items.append(Item(index, ident, []))
    if at != len(body) and "trailing" not in lenient:
        raise Malformed(f"{len(body) - at} bytes after the IDs")
    return items


def _read_id(model: Model, body: bytes, at: int) -> tuple[int, int]:
    end = at + model.id_length
    if end > len(body):
        raise Malformed("ID cut short")
    return int.from_bytes(body[at:end], "big"), end


def encode_id(model: Model, ident: int) -> bytes:
    return ident.to_bytes(model.id_length, "big")


# --- the replay window (D-RSP-15) -------------------------------------------------------------

NEWER, LATE, DUPLICATE, TOO_OLD = "newer", "late", "duplicate", "too old"


class ReplayWindow:
    """The newest sequence number seen and which of the `depth` before it were seen."""

    def __init__(self, depth: int = 64, remember: bool = True) -> None:
        self.depth = depth
        self.remember = remember
        self.newest: int | None = None
        self.seen = 0  # bit i: newest - i was seen

    def check(self, seq: int) -> str:
        """What the packet is, without taking it."""
        if self.newest is None:
            return NEWER
        ahead = (seq - self.newest) & 0xFFFF
        if 1 <= ahead <= 32767:
            return NEWER
        behind = (self.newest - seq) & 0xFFFF
        if behind > self.depth:
            return TOO_OLD
        if self.remember and self.seen >> behind & 1:
            return DUPLICATE
        return LATE

    def take(self, seq: int) -> None:
        """Record a packet that `check` let through and that authenticated."""
        mask = (1 << (self.depth + 1)) - 1
        if self.newest is None:
            self.newest, self.seen = seq, 1
            return
        ahead = (seq - self.newest) & 0xFFFF
        if 1 <= ahead <= 32767:
            self.seen = ((self.seen << ahead) | 1) & mask
            self.newest = seq
        else:
            self.seen |= 1 << ((self.newest - seq) & 0xFFFF)


# --- the security processor (D-RSP-21) --------------------------------------------------------


def hkdf_sha256(key: bytes, salt: bytes, info: bytes, length: int = 32) -> bytes:
    prk = hmac.new(salt, key, hashlib.sha256).digest()
    out, block, counter = b"", b"", 1
    while len(out) < length:
        block = hmac.new(prk, block + info + bytes([counter]), hashlib.sha256).digest()
        out += block
        counter += 1
    return out[:length]


def mac16(key: bytes, data: bytes) -> bytes:
    return hmac.new(key, data, hashlib.sha256).digest()[:16]


def aead_for(encryption: int, key: bytes) -> Any:
    from cryptography.hazmat.primitives.ciphers.aead import AESGCM, ChaCha20Poly1305

    return AESGCM(key) if encryption == AES_256_GCM else ChaCha20Poly1305(key)


def aead_nonce(index: int) -> bytes:
    return bytes(4) + index.to_bytes(8, "big")


class IndexEstimator:
    """The receiver's estimate of its peer's packet index (RFC 3711 §3.3.1)."""

    def __init__(self) -> None:
        self.roc = 0
        self.highest: int | None = None

    def estimate(self, seq: int) -> int:
        if self.highest is None:
            return seq
        s_l, roc = self.highest, self.roc
        if s_l < 32768:
            v = roc - 1 if seq - s_l > 32768 else roc
        else:
            v = roc + 1 if s_l - 32768 > seq else roc
        return max(v, 0) * 65536 + seq

    def update(self, index: int) -> None:
        roc, seq = divmod(index, 65536)
        if self.highest is None or (roc, seq) > (self.roc, self.highest):
            self.roc, self.highest = roc, seq
