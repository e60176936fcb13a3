"""The security processor (D-RSP-21): session keys, sealed packets, the MACs of HELLO and WELCOME.

"The Security processor manages robots ID and provides encryption capability" (paper §II.B). A
robot and the local systems allowed to drive it share a 256-bit key. Each session derives its own
key per direction with HKDF (RFC 5869), so a nonce need only be unique within one session and one
direction: it is the sender's 64-bit packet index (SRTP's, RFC 3711 §3.3.1), which grows by one a
packet. The 20-byte header is the associated data: a packet whose header was changed fails
authentication as surely as one whose body was.

Nothing here keeps time or state beyond the keys: the receiver's packet index comes from its
sequence window (`rctp.datastream.order.SequenceTracker.extended`).
"""

from __future__ import annotations

import enum
import hmac
from dataclasses import dataclass
from hashlib import sha256

from cryptography.exceptions import InvalidTag
from cryptography.hazmat.primitives import hashes
from cryptography.hazmat.primitives.ciphers.aead import AESGCM, ChaCha20Poly1305
from cryptography.hazmat.primitives.kdf.hkdf import HKDF

from rcmlconf.errors import EncodeError, ProtocolError
from rcmlconf.rsp.codec.header import Encryption
from rcmlconf.rsp.layout import HEADER_SIZE, MAC_SIZE, TAG_SIZE

#: The pre-shared key and every session key: 256 bits.
KEY_SIZE = 32
#: How a key file is made, for messages about a bad one.
KEY_RECIPE = "python -c 'import secrets; print(secrets.token_hex(32))'"


def key_from_file(data: bytes) -> bytes:
    """A pre-shared key (D-RSP-21) from a key file's bytes: 64 hex digits or 32 raw bytes;
    ValueError for anything else."""
    try:
        text = data.decode("ascii").strip()
        if len(text) == 2 * KEY_SIZE:
            return bytes.fromhex(text)
    except (UnicodeDecodeError, ValueError):
        pass
    if len(data) == KEY_SIZE:
        return data
    raise ValueError(
        f"a key is {2 * KEY_SIZE} hex digits or {KEY_SIZE} bytes (make one: {KEY_RECIPE})"
    )


#: D-RSP-21: a session ends before its index needs more than 48 bits (178 years at 50 Hz).
MAX_INDEX = (1 << 48) - 1
_RULE = "R-RSP-18"


class Direction(enum.Enum):
    """Who sends: the local system downlink, the robot uplink (both ways for ACK and BYE)."""

    DOWNLINK = b"RSP/1 downlink"
    UPLINK = b"RSP/1 uplink"


#: The AEAD each encryption byte selects; 0 (`Encryption.NONE`) has none.
AEADS: dict[Encryption, type[AESGCM] | type[ChaCha20Poly1305]] = {
    Encryption.AES_256_GCM: AESGCM,
    Encryption.CHACHA20_POLY1305: ChaCha20Poly1305,
}


def check_key(key: bytes) -> bytes:
    if len(key) != KEY_SIZE:
        raise EncodeError(f"a key is {KEY_SIZE} bytes, not {len(key)}")
    return key


def session_key(
    psk: bytes, client_nonce: bytes, robot_nonce: bytes, session_id: int, direction: Direction
) -> bytes:
    """D-RSP-21: one key per session and direction, from the pre-shared key."""
    hkdf = HKDF(
        algorithm=hashes.SHA256(),
        length=KEY_SIZE,
        salt=client_nonce + robot_nonce,
        info=direction.value + session_id.to_bytes(6, "big"),
    )
    return hkdf.derive(check_key(psk))


def mac(psk: bytes, data: bytes) -> bytes:
    """The MAC of a HELLO or WELCOME: HMAC-SHA256 over what precedes it, cut to 16 bytes."""
    return hmac.digest(check_key(psk), data, sha256)[:MAC_SIZE]


def mac_matches(psk: bytes, data: bytes, given: bytes) -> bool:
    """In constant time, so that a wrong MAC tells nothing of the right one."""
    return hmac.compare_digest(mac(psk, data), given)


def nonce(index: int) -> bytes:
    """D-RSP-21: 4 zero bytes and the 64-bit packet index."""
    return bytes(4) + index.to_bytes(8, "big")


@dataclass(frozen=True)
class Sealer:
    """Seals and opens the packets of one direction of one session."""

    cipher: Encryption
    key: bytes

    def seal(self, header: bytes, body: bytes, index: int) -> bytes:
        """The body encrypted, with its tag: what follows the header on the wire."""
        if not 0 <= index <= MAX_INDEX:
            raise EncodeError(f"packet index {index}: end the session and open a new one")
        return AEADS[self.cipher](self.key).encrypt(nonce(index), body, header)

    def open(self, header: bytes, sealed: bytes, index: int) -> bytes:
        """The body of a sealed packet; a ProtocolError when it fails authentication."""
        if index < 0:  # behind the session's first packet: no packet of this key has it
            raise ProtocolError("the packet is older than the session", HEADER_SIZE, _RULE)
        if len(sealed) < TAG_SIZE:
            raise ProtocolError(
                f"{len(sealed)} bytes after the header, fewer than a tag", HEADER_SIZE, _RULE
            )
        try:
            return AEADS[self.cipher](self.key).decrypt(nonce(index), sealed, header)
        except InvalidTag:
            raise ProtocolError("the packet fails authentication", HEADER_SIZE, _RULE) from None
