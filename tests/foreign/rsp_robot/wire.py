"""RSP packets: the 20-byte header (D-RSP-10), packet types (D-RSP-11), the replay window
(D-RSP-15) and the security processor (D-RSP-21)."""

from __future__ import annotations

import hashlib
import hmac
import struct
from dataclasses import dataclass
from typing import Any

VERSION = 1
NO_MODEL = 0  # no model has model ID 0: a packet with it is malformed (D-RSP-10)
HEADER = struct.Struct(">BHBBHI6sHB")
assert HEADER.size == 20

HELLO, WELCOME, REFUSED, DOWNLINK, UPLINK, ACK, BYE, PERIOD = range(1, 9)
TYPE_NAMES = {1: "HELLO", 2: "WELCOME", 3: "REFUSED", 4: "DOWNLINK", 5: "UPLINK", 6: "ACK"}
TYPE_NAMES |= {7: "BYE", 8: "PERIOD"}

NONE, AES_256_GCM, CHACHA20_POLY1305 = 0, 1, 2
REFUSED_UNKNOWN_MODEL, REFUSED_ENCRYPTION, REFUSED_BUSY, REFUSED_NOT_AUTHENTICATED = 1, 2, 3, 4
BYE_CLOSED, BYE_TIMEOUT, BYE_SHUTDOWN = 0, 1, 2

NONCE_LENGTH = 16
MAC_LENGTH = 16
TAG_LENGTH = 16
WINDOW = 64  # a packet more than 64 behind the newest is dropped (D-RSP-15)
MIN_PERIOD_MS, MAX_PERIOD_MS = 5, 10_000


@dataclass
class Header:
    version: int
    model_id: int
    encryption: int
    type: int
    seq: int
    timestamp: int
    session_id: int
    last_received: int
    buffer: int

    def pack(self) -> bytes:
        return HEADER.pack(
            self.version,
            self.model_id,
            self.encryption,
            self.type,
            self.seq & 0xFFFF,
            self.timestamp & 0xFFFFFFFF,
            self.session_id.to_bytes(6, "big"),
            self.last_received & 0xFFFF,
            self.buffer,
        )

    @classmethod
    def unpack(cls, data: bytes) -> Header:
        v, model, enc, kind, seq, ts, sid, last, buf = HEADER.unpack_from(data)
        return cls(v, model, enc, kind, seq, ts, int.from_bytes(sid, "big"), last, buf)


def serial_delta(a: int, b: int, bits: int) -> int:
    """How far a is ahead of b, in -(2^(bits-1)) .. 2^(bits-1) - 1."""
    half = 1 << (bits - 1)
    return ((a - b + half) % (1 << bits)) - half


def mac(psk: bytes, data: bytes) -> bytes:
    return hmac.new(psk, data, hashlib.sha256).digest()[:MAC_LENGTH]


class ReplayWindow:
    """The receiver's newest packet index and which of the 64 before it were seen (D-RSP-15).

    Sequence numbers are extended to 64-bit packet indexes (SRTP, RFC 3711 §3.3.1): a sequence
    number 1 to 32,767 ahead of the newest is newer, any other is behind.
    """

    def __init__(self, first_seq: int, depth: int = WINDOW) -> None:
        self.newest = first_seq
        self.seen = 1  # bit i: index newest - i was taken
        self.depth = depth

    def estimate(self, seq: int) -> int:
        delta = (seq - self.newest) % 65536
        if 1 <= delta <= 32767:
            return self.newest + delta
        return self.newest - ((65536 - delta) % 65536)

    def check(self, index: int) -> str | None:
        """'newer', 'late', or None for a packet to drop (too old, or seen before)."""
        if index > self.newest:
            return "newer"
        behind = self.newest - index
        if index < 0 or behind > self.depth or self.seen >> behind & 1:
            return None
        return "late"

    def mark(self, index: int) -> None:
        if index > self.newest:
            shift = index - self.newest
            self.seen = (self.seen << shift | 1) & ((1 << (self.depth + 1)) - 1)
            self.newest = index
        else:
            self.seen |= 1 << (self.newest - index)


class Cipher:
    """One direction's AEAD of an encrypted session (D-RSP-21)."""

    def __init__(self, algorithm: int, key: bytes) -> None:
        from cryptography.hazmat.primitives.ciphers.aead import AESGCM, ChaCha20Poly1305

        self.aead: Any = AESGCM(key) if algorithm == AES_256_GCM else ChaCha20Poly1305(key)

    @staticmethod
    def nonce(index: int) -> bytes:
        return bytes(4) + index.to_bytes(8, "big")

    def seal(self, index: int, header: bytes, body: bytes) -> bytes:
        return bytes(self.aead.encrypt(self.nonce(index), body, header))

    def open(self, index: int, header: bytes, sealed: bytes) -> bytes | None:
        from cryptography.exceptions import InvalidTag

        try:
            return bytes(self.aead.decrypt(self.nonce(index), sealed, header))
        except InvalidTag:
            return None


def derive_key(psk: bytes, client_nonce: bytes, robot_nonce: bytes, info: bytes) -> bytes:
    from cryptography.hazmat.primitives import hashes
    from cryptography.hazmat.primitives.kdf.hkdf import HKDF

    hkdf = HKDF(algorithm=hashes.SHA256(), length=32, salt=client_nonce + robot_nonce, info=info)
    return hkdf.derive(psk)


def read_psk(data: bytes) -> bytes:
    """A pre-shared key file: 64 hexadecimal digits (white space around them ignored), or the
    32 bytes themselves."""
    text = data.strip()
    if len(text) == 64:
        try:
            return bytes.fromhex(text.decode("ascii"))
        except (UnicodeDecodeError, ValueError):
            pass
    if len(data) == 32:
        return data
    raise ValueError("a key file holds 64 hex digits or 32 bytes")
