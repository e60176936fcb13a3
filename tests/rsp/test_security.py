"""The security processor (D-RSP-21): keys per session and direction, sealed packets, MACs."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from rcmlconf.errors import EncodeError, ProtocolError
from rcmlconf.rctp.datastream.order import SequenceTracker
from rcmlconf.rsp.codec.header import Encryption
from rcmlconf.rsp.layout import MAC_SIZE
from rcmlconf.rsp.security import (
    AEADS,
    KEY_SIZE,
    Direction,
    Sealer,
    mac,
    mac_matches,
    nonce,
    session_key,
)

PSK = bytes(range(KEY_SIZE))
CLIENT, ROBOT = b"c" * 16, b"r" * 16
HEADER = bytes(range(20))


def key(direction: Direction = Direction.DOWNLINK, session: int = 0xA1B2C3D4E5F6) -> bytes:
    return session_key(PSK, CLIENT, ROBOT, session, direction)


def test_keys_differ_by_direction_session_and_nonces() -> None:
    keys = {
        key(),
        key(Direction.UPLINK),
        key(session=1),
        session_key(PSK, ROBOT, CLIENT, 0xA1B2C3D4E5F6, Direction.DOWNLINK),
        session_key(bytes(KEY_SIZE), CLIENT, ROBOT, 0xA1B2C3D4E5F6, Direction.DOWNLINK),
    }
    assert len(keys) == 5
    assert all(len(k) == KEY_SIZE for k in keys)
    assert key() == key()  # both ends derive the same


def test_a_key_of_another_size_is_refused() -> None:
    with pytest.raises(EncodeError):
        session_key(b"short", CLIENT, ROBOT, 1, Direction.UPLINK)


@pytest.mark.parametrize("cipher", list(AEADS))
def test_a_sealed_body_opens_with_its_header_and_index_only(cipher: Encryption) -> None:
    sealer = Sealer(cipher, key())
    sealed = sealer.seal(HEADER, b"device map and payloads", 70000)
    assert len(sealed) == len(b"device map and payloads") + 16
    assert sealer.open(HEADER, sealed, 70000) == b"device map and payloads"
    for header, body, index in (
        (HEADER[:-1] + b"\xff", sealed, 70000),  # the header is authenticated
        (HEADER, sealed[:-1] + bytes([sealed[-1] ^ 1]), 70000),  # so is the body
        (HEADER, sealed, 70001),  # another index is another nonce
        (HEADER, sealed[:10], 70000),  # shorter than a tag
        (HEADER, sealed, -1),
    ):
        with pytest.raises(ProtocolError) as failure:
            sealer.open(header, body, index)
        assert failure.value.rule == "R-RSP-18"
    with pytest.raises(ProtocolError):
        Sealer(cipher, key(Direction.UPLINK)).open(HEADER, sealed, 70000)


def test_nonces_never_repeat_within_a_session() -> None:
    assert len({nonce(i) for i in range(0, 1 << 20, 4099)}) == len(range(0, 1 << 20, 4099))
    assert nonce(1) == bytes(11) + b"\x01"
    with pytest.raises(EncodeError):
        Sealer(Encryption.AES_256_GCM, key()).seal(HEADER, b"", 1 << 48)


def test_macs() -> None:
    digest = mac(PSK, b"hello")
    assert len(digest) == MAC_SIZE
    assert mac_matches(PSK, b"hello", digest)
    assert not mac_matches(PSK, b"hellO", digest)
    assert not mac_matches(bytes(KEY_SIZE), b"hello", digest)


@given(st.lists(st.integers(0, 32), min_size=1, max_size=300))
def test_the_receiver_finds_the_senders_index_across_wraps(gaps: list[int]) -> None:
    """SRTP's index estimate (D-RSP-21) from the 16-bit sequence number, with losses between."""
    window = SequenceTracker()
    index = 0
    for gap in gaps:
        index += gap * 1000 + 1  # up to 32,000 lost in a row: less than half the sequence space
        sequence = index & 0xFFFF
        assert window.extended(sequence) == index
        window.see(sequence)
