"""A UDP socket on the loop read several datagrams a wake-up: the RCTP server's data stream
(D-RCTP-28) and the RSP robot's port (D-RSP-9).

asyncio's datagram transport reads one datagram a turn of the loop. A flood of datagrams at the
port (garbage, spoofed or replayed packets, or one peer's) then fills the socket's receive buffer
whenever the loop is busy, and the kernel drops whatever comes next, whoever sent it: a
legitimate peer's packets with the rest, until its session times out although the peer never
stopped (an RCTP server STOPped a writer's stream for silence, R-RCTP-45; the RSP robot lost a
local system's DOWNLINKs). So the socket is read up to `DATAGRAMS_A_TURN` at a wake-up (a
datagram of no session costs a look-up, D-RCTP-32) into a receive buffer of `RECEIVE_BUFFER`
bytes (the kernel caps it at net.core.rmem_max), and the timers due run between wake-ups as
before.

Sending is one `sendto` a datagram, as asyncio's transport does; a datagram that finds the send
buffer full is dropped, as the network may drop any (the streams' next values follow).
"""

from __future__ import annotations

import asyncio
import logging
import socket
from collections.abc import Callable
from typing import Any

Address = tuple[str, int]
Received = Callable[[bytes, Address], None]

#: Datagrams read at one wake-up at most: what a beat due meanwhile may wait for.
DATAGRAMS_A_TURN = 64
#: Bytes of receive buffer asked for: about 2,000 datagrams of a flood kept while the loop is
#: busy for a while.
RECEIVE_BUFFER = 4 << 20
#: The largest UDP payload (IPv4).
MAX_DATAGRAM = 65_507
_NUMERIC = socket.AI_NUMERICHOST | socket.AI_NUMERICSERV


class DataSocket:
    """A bound UDP socket on the loop: `received(data, address)` for each datagram; what it
    meets besides (an ICMP error of an earlier send) is a debug line of `log`. What the RSP
    adapters use of a datagram transport (`rsp.batch.Datagrams`) too."""

    def __init__(
        self,
        loop: asyncio.AbstractEventLoop,
        sock: socket.socket,
        received: Received,
        log: logging.Logger,
    ) -> None:
        self.sock = sock
        self._loop = loop
        self._received = received
        self._log = log
        #: Datagrams not sent, the send buffer full.
        self.unsent = 0
        sock.setblocking(False)
        try:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, RECEIVE_BUFFER)
        except OSError as error:  # a system that refuses the size: its default is kept
            log.debug("UDP receive buffer of %d bytes: %s", RECEIVE_BUFFER, error)
        loop.add_reader(sock.fileno(), self._read)

    @classmethod
    async def bind(
        cls, host: str, port: int, received: Received, log: logging.Logger
    ) -> DataSocket:
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
            return cls(loop, sock, received, log)
        raise failure

    @property
    def port(self) -> int:
        return int(self.sock.getsockname()[1])

    def get_extra_info(self, name: str, default: Any = None) -> Any:
        return self.sock.getsockname() if name == "sockname" else default

    def is_closing(self) -> bool:
        return self.sock.fileno() < 0

    def _read(self) -> None:
        for _ in range(DATAGRAMS_A_TURN):
            try:
                data, address = self.sock.recvfrom(MAX_DATAGRAM)
            except (BlockingIOError, InterruptedError):
                return
            except OSError as error:  # an ICMP error of an earlier send: the socket goes on
                self._log.debug("UDP: %s", error)
                continue
            self._received(data, (str(address[0]), int(address[1])))

    def sendto(self, data: bytes, addr: Address | None = None) -> None:
        assert addr is not None, "the socket is not connected: sendto names where"
        try:
            self.sock.sendto(data, addr)
        except (BlockingIOError, InterruptedError):
            self.unsent += 1
        except OSError as error:  # unreachable, or an ICMP error of an earlier send
            self._log.debug("UDP: %s", error)

    def close(self) -> None:
        if self.sock.fileno() >= 0:
            self._loop.remove_reader(self.sock.fileno())
            self.sock.close()
