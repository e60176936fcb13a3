"""Many RSP endpoints on one asyncio loop, batched: one reader and one clock for all of them.

The asyncio adapter gives every robot (`ReferenceRobot.start()`) and every local system
(`Simulacrum.open()`) a datagram transport and a loop timer of its own. With hundreds of them in
one loop that costs more than RSP does (bench/rsp_pairs_scale.py): each datagram is a wake-up of
the loop's selector, a handle run and a `recvfrom` of 256 KiB that the transport allocates and
shrinks again; each period of each endpoint, a timer handle made, pushed and popped. A `Batch`
serves them all with:

- one reader: every endpoint keeps a UDP socket of its own, as D-RSP-9 has it (a robot on its
  port, a local system on any port), but the sockets are in one epoll set of the batch's, and the
  set's descriptor is the only one the loop watches for them. One wake-up reads one datagram from
  each of up to `READS_A_WAKEUP` sockets that have one, into one buffer; a socket with more, or
  not reached, stays ready (the set is level-triggered, and hands out the ones it did not report
  first) and is read at a next wake-up, so no socket waits on a busier one's backlog, no read
  ends in EAGAIN, and no beat waits for every datagram that came meanwhile: the loop runs the
  timers due after each wake-up's reads;
- one clock: an endpoint's timer is a place on a `BeatClock`, one loop timer per millisecond for
  every endpoint whose deadline falls in it, called back at the millisecond's end: never early,
  since an RSP endpoint sends only when its beat has come (D-RSP-13), and at most 1 ms late, the
  same amount at every beat of a session, whose phase in the millisecond does not change.

Sending stays one `sendto` a datagram: Python has no `sendmmsg`, and on loopback the kernel's
delivery, not the system call, is most of a datagram's cost. Linux only (epoll).

    batch = Batch(asyncio.get_running_loop())
    await robot.start(batch)             # ReferenceRobot
    await simulacrum.open(batch=batch)   # Simulacrum
"""

from __future__ import annotations

import asyncio
import select
import socket
from collections.abc import Callable
from typing import Any, Protocol

from rcmlconf.reference.timers import BeatClock

Address = tuple[str, int]
Received = Callable[[bytes, Address], None]
#: The largest UDP payload (IPv4): RSP packets carry `bytes` payloads (D-RSP-22's audio).
MAX_DATAGRAM = 65_507
#: Receive buffers of this size (the kernel caps it at net.core.rmem_max): a socket that a busy
#: millisecond leaves unread for a while keeps what came meanwhile.
RECEIVE_BUFFER = 1 << 20
#: Datagrams read at one wake-up at most. A beat due meanwhile waits for that many, about half a
#: millisecond of RSP's work, rather than for all that came: at 200 pairs in one process, reading
#: every ready socket at once put beats 15 ms late at the 99th percentile; 32 at a time, 1.7 to
#: 2.1 ms; 16 or 8, 1.0 to 1.9 ms (bench/rsp_pairs_scale.py).
READS_A_WAKEUP = 16


class Datagrams(Protocol):
    """What the RSP adapters use of a datagram transport: asyncio's, or a `Port`."""

    def sendto(self, data: bytes, addr: Address | None = None) -> None: ...

    def get_extra_info(self, name: str, default: Any = None) -> Any: ...

    def is_closing(self) -> bool: ...

    def close(self) -> None: ...


class Timer(Protocol):
    """What the RSP adapters use of a timer: a `LoopTimer`, or a `Batch.timer`."""

    def set(self, at: float | None) -> None: ...


class Port:
    """One endpoint's UDP socket in a batch, with the part of asyncio's datagram transport that
    the adapters use. A connected one (a local system's, to its robot) takes datagrams from
    that address only, as asyncio's `remote_addr` does."""

    __slots__ = ("_batch", "_closed", "received", "sock", "unsent")

    def __init__(self, batch: Batch, sock: socket.socket, received: Received) -> None:
        self._batch = batch
        self._closed = False
        self.sock = sock
        self.received = received
        #: Datagrams the kernel did not take (a full buffer, an ICMP error of an earlier one).
        self.unsent = 0

    def sendto(self, data: bytes, addr: Address | None = None) -> None:
        try:
            if addr is None:
                self.sock.send(data)
            else:
                self.sock.sendto(data, addr)
        except OSError:
            # Lost, as UDP may lose any datagram: RSP sends its state again every beat and
            # repeats what must arrive (D-RSP-13, D-RSP-17); asyncio's transport would log it.
            self.unsent += 1

    def get_extra_info(self, name: str, default: Any = None) -> Any:
        if name == "sockname":
            return self.sock.getsockname()
        if name == "peername":
            try:
                return self.sock.getpeername()
            except OSError:
                return default
        return default

    def is_closing(self) -> bool:
        return self._closed

    def close(self) -> None:
        if not self._closed:
            self._closed = True
            self._batch._forget(self)
            self.sock.close()


class _Place:
    """An endpoint's timer: its place on the batch's clock."""

    __slots__ = ("_clock", "fire")

    def __init__(self, clock: BeatClock[_Place], fire: Callable[[], None]) -> None:
        self._clock = clock
        self.fire = fire

    def set(self, at: float | None) -> None:
        self._clock.set(self, at)


class Batch:
    """The sockets and timers of many RSP endpoints on one loop (see the module's text)."""

    def __init__(self, loop: asyncio.AbstractEventLoop) -> None:
        self.loop = loop
        self._epoll = select.epoll()
        self._ports: dict[int, Port] = {}
        self._buffer = bytearray(MAX_DATAGRAM)
        self._view = memoryview(self._buffer)
        self._clock: BeatClock[_Place] = BeatClock(loop, self._due, late=True)
        loop.add_reader(self._epoll.fileno(), self._readable)

    def open(
        self,
        received: Received,
        *,
        local: Address = ("127.0.0.1", 0),
        remote: Address | None = None,
    ) -> Port:
        """A UDP socket bound to `local` (and connected to `remote`), whose datagrams go to
        `received` with their source address."""
        family = socket.AF_INET6 if ":" in (remote or local)[0] else socket.AF_INET
        sock = socket.socket(family, socket.SOCK_DGRAM)
        try:
            sock.setblocking(False)
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, RECEIVE_BUFFER)
            if remote is None:
                sock.bind(local)
            else:
                sock.connect(remote)
            self._epoll.register(sock.fileno(), select.EPOLLIN)
        except BaseException:
            sock.close()
            raise
        port = Port(self, sock, received)
        self._ports[sock.fileno()] = port
        return port

    def timer(self, fire: Callable[[], None]) -> Timer:
        """A timer whose deadlines fall on the batch's clock; `fire` is called when one comes."""
        return _Place(self._clock, fire)

    def close(self) -> None:
        """Every port closed, and the batch's reader taken off the loop."""
        for port in list(self._ports.values()):
            port.close()
        self.loop.remove_reader(self._epoll.fileno())
        self._epoll.close()

    def _forget(self, port: Port) -> None:
        fileno = port.sock.fileno()
        if self._ports.pop(fileno, None) is not None:
            self._epoll.unregister(fileno)

    def _readable(self) -> None:
        """One datagram from each of up to READS_A_WAKEUP sockets that have one (bounded: one
        poll, one read a socket); the loop runs the timers due, then calls again for the rest."""
        buffer, view, ports = self._buffer, self._view, self._ports
        for fileno, _ in self._epoll.poll(0, READS_A_WAKEUP):
            port = ports.get(fileno)
            if port is None:
                continue
            try:
                size, addr = port.sock.recvfrom_into(buffer)
            except OSError:
                # Nothing after all, or an ICMP error (a connected socket's peer not there yet:
                # a HELLO is repeated, D-RSP-12).
                continue
            port.received(bytes(view[:size]), addr)

    @staticmethod
    def _due(places: list[_Place]) -> None:
        for place in places:
            place.fire()
