"""A probe's UDP socket: each datagram that comes goes to the probe's `arrived`, with its source as
(host, port) and the time it reached the socket, as the probe will keep them.

- The time is the kernel's receive timestamp (D-RSP-26, D-RCTP-33), on the event loop's clock.
  A datagram read late because the harness's loop was busy, or its process kept off the CPU,
  still shows when it came. Linux stamps a socket's datagrams once `SIOCGSTAMPNS` has been asked
  for, and that ioctl then gives the stamp of the datagram just read. Where it fails, the time
  is the loop's clock as the datagram is read.
- Its bytes are copied first. asyncio reads a datagram into a buffer of 256 KiB and gives the
  buffer cut down to the datagram: kept as it is (in the transcript, in what a probe received),
  each such datagram holds on to a page of memory or more, and a flood of them to hundreds of MiB.
- The CPU time the harness spends handling it is the target's load (`loopwatch.charge`; the
  garbage collector's pauses not counted): a hold of the harness's loop spent on it excuses no
  lateness of the target's (D-RSP-26, D-RCTP-33).
"""

from __future__ import annotations

import asyncio
import contextlib
import fcntl
import functools
import socket
import struct
import time
from collections.abc import Callable

from rcmlconf.conformance.loopwatch import charge, cpu_spent
from rcmlconf.conformance.transcript import Address

#: (bytes, source, arrival on the loop's clock).
Arrived = Callable[[bytes, Address, float], None]

#: linux/sockios.h: the receive time of the last datagram read, as a struct timespec.
_SIOCGSTAMPNS = 0x8907
_TIMESPEC = struct.Struct("@qq")


def _stamp(fd: int) -> float:
    """The kernel's receive time of the datagram last read from `fd`, on the wall clock.
    OSError where there is none: the first ask only turns the stamps on."""
    seconds: int
    nanoseconds: int
    seconds, nanoseconds = _TIMESPEC.unpack(fcntl.ioctl(fd, _SIOCGSTAMPNS, bytes(_TIMESPEC.size)))
    return seconds + nanoseconds * 1e-9


def _stamp_from_now_on(fd: int) -> None:
    """Ask the kernel to stamp what `fd` receives from now on."""
    with contextlib.suppress(OSError):
        _stamp(fd)


@functools.cache
def arrival_clock() -> tuple[str, str]:
    """Which clock times the datagrams a probe receives: ("kernel", "") where the kernel stamps
    them, else ("loop", why not). Found once a process, with one datagram sent to itself."""
    try:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
            sock.bind(("127.0.0.1", 0))
            sock.settimeout(1.0)
            _stamp_from_now_on(sock.fileno())
            sock.sendto(b"stamp?", sock.getsockname())
            sock.recv(16)
            stamp = _stamp(sock.fileno())
    except OSError as error:
        return "loop", f"SIOCGSTAMPNS: {error.strerror or error}"
    if stamp <= 0:
        return "loop", "SIOCGSTAMPNS gave no time"
    return "kernel", ""


class Inbound(asyncio.DatagramProtocol):
    """Datagrams to `arrived` (None: dropped), errors the socket meets to `error`."""

    def __init__(
        self, arrived: Arrived | None = None, error: Callable[[Exception], None] | None = None
    ) -> None:
        self.arrived = arrived
        self.error = error
        self._fd = -1
        self._clock = time.monotonic

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        self._clock = asyncio.get_running_loop().time
        sock = transport.get_extra_info("socket")
        if sock is None:
            return
        self._fd = sock.fileno()
        _stamp_from_now_on(self._fd)

    def datagram_received(self, data: bytes, addr: tuple[str | int, ...]) -> None:
        arrived = self.arrived
        if arrived is None:
            return
        at = self._arrival()
        started = cpu_spent()
        try:
            arrived(bytes(memoryview(data)), (str(addr[0]), int(addr[1])), at)
        finally:
            charge(cpu_spent() - started)

    def error_received(self, exc: Exception) -> None:
        if self.error is not None:
            self.error(exc)

    def _arrival(self) -> float:
        """When the datagram just read reached the socket, on the loop's clock: the kernel's
        wall-clock stamp moved by how long ago it was, never later than now."""
        now = self._clock()
        if self._fd < 0:
            return now
        try:
            ago = time.time() - _stamp(self._fd)
        except OSError:
            return now
        return now - ago if ago > 0 else now
