"""Packets a case alters or makes byte by byte, to send an RSP robot what a well-behaved local
system never would: a packet the core built with bytes written over it (`patch`) or a bit flipped
(`flip`), and a HELLO of any model, encryption byte and MAC (`hello_packet`, D-RSP-11)."""

from __future__ import annotations

import struct

from rcmlconf.conformance.probes.rsp_datagram import HEADER_LAYOUT
from rcmlconf.rsp.codec import Encryption, PacketType
from rcmlconf.rsp.layout import MAC_SIZE
from rcmlconf.rsp.security import mac


def patch(data: bytes, offset: int, new: bytes) -> bytes:
    """`data` with `new` written over it at `offset`."""
    return data[:offset] + new + data[offset + len(new) :]


def flip(data: bytes, offset: int, mask: int = 0x01) -> bytes:
    return patch(data, offset, bytes([data[offset] ^ mask]))


def hello_packet(
    model_id: int,
    encryption: int,
    nonce: bytes,
    period_ms: int,
    *,
    sequence: int = 0,
    psk: bytes | None = None,
    signed: bool | None = None,
) -> bytes:
    """A HELLO of any model and encryption byte (D-RSP-11), its MAC made with `psk` (D-RSP-21);
    `signed` says whether it carries a MAC (by default: when the encryption is not NONE)."""
    header = HEADER_LAYOUT.pack(1, model_id, encryption, PacketType.HELLO, sequence, 0, 0, 0, 0, 0)
    unsigned = header + nonce + struct.pack(">H", period_ms)
    if signed is None:
        signed = encryption != Encryption.NONE
    if not signed:
        return unsigned
    return unsigned + (mac(psk, unsigned) if psk is not None else bytes(MAC_SIZE))
