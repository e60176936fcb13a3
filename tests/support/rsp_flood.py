"""A flood of hostile datagrams at an RSP robot, sent from a process of its own (issue 18)."""

from __future__ import annotations

import random
import socket
import time

from rcmlconf.rsp.codec.header import HEADER, SEQUENCE_AT

#: Hostile datagrams of each kind, and of each kind in a burst every PACE seconds: about 10,000
#: datagrams a second, bench/hostile_load.py's garbage UDP.
EACH = 3000
BURST, PACE = 10, 0.003


def spoofed(packet: bytes, ahead: int) -> bytes:
    """`packet` with its sequence number `ahead` of its own: newer, were it the session's (and
    bench/hostile_rsp.py's flood's)."""
    (sequence,) = HEADER.unpack_from(packet)[4:5]
    data = bytearray(packet)
    data[SEQUENCE_AT : SEQUENCE_AT + 2] = ((sequence + ahead) & 0xFFFF).to_bytes(2, "big")
    return bytes(data)


def flood(robot: tuple[str, int], old: list[bytes]) -> None:
    """From another address: garbage, the session's packets made newer (a spoofed session ID),
    and its old packets replayed, interleaved; in bursts, so that the flood fits the robot's
    receive buffer on any system (net.core.rmem_max may be 200 KiB): the test is of what the
    robot does with the datagrams, not of what the kernel drops."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("127.0.0.2", 0))
        for index in range(EACH):
            if index % BURST == 0:
                time.sleep(PACE)
            replay = old[index % len(old)]
            for data in (
                random.randbytes(random.randrange(1, 200)),
                spoofed(replay, 1 + index),
                replay,
            ):
                sock.sendto(data, robot)  # blocking: none lost here for want of buffer
