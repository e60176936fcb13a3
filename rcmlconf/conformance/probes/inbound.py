"""A probe's UDP socket: each datagram that comes goes to the probe's `arrived`, with its source as
(host, port), as the probe will keep it.

- Its bytes are copied first. asyncio reads a datagram into a buffer of 256 KiB and gives the
  buffer cut down to the datagram: kept as it is (in the transcript, in what a probe received),
  each such datagram holds on to a page of memory or more, and a flood of them to hundreds of MiB.
- The CPU time the harness spends handling it is the target's load (`loopwatch.charge`; the
  garbage collector's pauses not counted): a hold of the harness's loop spent on it excuses no
  lateness of the target's (D-RSP-26, D-RCTP-33).
"""

from __future__ import annotations

import asyncio
from collections.abc import Callable

from rcmlconf.conformance.loopwatch import charge, cpu_spent
from rcmlconf.conformance.transcript import Address

Arrived = Callable[[bytes, Address], None]


class Inbound(asyncio.DatagramProtocol):
    """Datagrams to `arrived` (None: dropped), errors the socket meets to `error`."""

    def __init__(
        self, arrived: Arrived | None = None, error: Callable[[Exception], None] | None = None
    ) -> None:
        self.arrived = arrived
        self.error = error

    def datagram_received(self, data: bytes, addr: tuple[str | int, ...]) -> None:
        arrived = self.arrived
        if arrived is None:
            return
        started = cpu_spent()
        try:
            arrived(bytes(memoryview(data)), (str(addr[0]), int(addr[1])))
        finally:
            charge(cpu_spent() - started)

    def error_received(self, exc: Exception) -> None:
        if self.error is not None:
            self.error(exc)
