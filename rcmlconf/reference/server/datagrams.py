"""The data stream's one UDP socket (D-RCTP-28), read several datagrams a wake-up.

asyncio's datagram transport reads one datagram a turn of the loop. A flood of datagrams at the
data port (garbage, or one peer's) then fills the socket's receive buffer whenever the loop is
busy, and the kernel drops whatever comes next, whoever sent it: a legitimate writer's DATA with
the rest, until the server STOPs its stream for silence (R-RCTP-45) although the writer never
stopped. So the socket is read up to `DATAGRAMS_A_TURN` at a wake-up (a datagram of no session
costs a dictionary look-up, D-RCTP-32) into a receive buffer of `RECEIVE_BUFFER` bytes (the
kernel caps it at net.core.rmem_max), and the beats due run between wake-ups as before.

Sending is one `sendto` a datagram, as asyncio's transport does; a datagram that finds the send
buffer full is dropped, as the network may drop any (the streams' next values follow).
"""

from __future__ import annotations

import asyncio
import logging
import socket
from collections.abc import Callable

Address = tuple[str, int]
Received = Callable[[bytes, Address], None]

log = logging.getLogger("rcmlconf.server")

#: Datagrams read at one wake-up at most: what a beat due meanwhile may wait for.
DATAGRAMS_A_TURN = 64
#: Bytes of receive buffer asked for: about 2,000 datagrams of a flood kept while the loop is
#: busy for a while.
RECEIVE_BUFFER = 4 << 20
#: The largest UDP payload (IPv4).
MAX_DATAGRAM = 65_507
_NUMERIC = socket.AI_NUMERICHOST | socket.AI_NUMERICSERV


class DataSocket:
    """A bound UDP socket on the loop: `received(data, address)` for each datagram."""

    def __init__(
        self, loop: asyncio.AbstractEventLoop, sock: socket.socket, received: Received
    ) -> None:
        self.sock = sock
        self._loop = loop
        self._received = received
        #: Datagrams not sent, the send buffer full.
        self.unsent = 0
        sock.setblocking(False)
        try:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, RECEIVE_BUFFER)
        except OSError as error:  # a system that refuses the size: its default is kept
            log.debug("data stream: receive buffer of %d bytes: %s", RECEIVE_BUFFER, error)
        loop.add_reader(sock.fileno(), self._read)

    @classmethod
    async def bind(cls, host: str, port: int, received: Received) -> DataSocket:
        """The socket bound to `host` (resolved as asyncio's `local_addr` is: the first
        address that binds) and `port` (0: a free one); the last OSError if none binds."""
        loop = asyncio.get_running_loop()
        try:  # an address as numbers needs no look-up, and no wait
            infos = socket.getaddrinfo(host, port, type=socket.SOCK_DGRAM, flags=_NUMERIC)
        except socket.gaierror:
            infos = await loop.getaddrinfo(host, port, type=socket.SOCK_DGRAM)
        failure: OSError = OSError(f"no address for {host!r}")
        for family, kind, proto, _name, address in infos:
            sock = socket.socket(family, kind, proto)
            try:
                sock.bind(address)
            except OSError as error:
                sock.close()
                failure = error
                continue
            return cls(loop, sock, received)
        raise failure

    @property
    def port(self) -> int:
        return int(self.sock.getsockname()[1])

    def _read(self) -> None:
        for _ in range(DATAGRAMS_A_TURN):
            try:
                data, address = self.sock.recvfrom(MAX_DATAGRAM)
            except (BlockingIOError, InterruptedError):
                return
            except OSError as error:  # an ICMP error of an earlier send: the socket goes on
                log.debug("data stream: %s", error)
                continue
            self._received(data, (str(address[0]), int(address[1])))

    def sendto(self, data: bytes, address: Address) -> None:
        try:
            self.sock.sendto(data, address)
        except (BlockingIOError, InterruptedError):
            self.unsent += 1
        except OSError as error:  # unreachable, or an ICMP error of an earlier send
            log.debug("data stream: %s", error)

    def close(self) -> None:
        if self.sock.fileno() >= 0:
            self._loop.remove_reader(self.sock.fileno())
            self.sock.close()
