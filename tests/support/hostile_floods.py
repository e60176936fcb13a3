"""Hostile peers that flood the harness (issue 27), each a process of its own that prints its
port and then serves until killed (`flooding` starts one for a test):

    python tests/support/hostile_floods.py robot [--garbage]   # an RSP robot of CUBO
    python tests/support/hostile_floods.py stream              # an RCTP server of the rover

The robot answers HELLO as the core's endpoint does, then sends its session's peer UPLINKs as
fast as it can until the session ends (`--garbage`: random bytes instead, from another port,
which a local system ignores, R-RSP-18; its session's own UPLINKs keep their pace). The server is
the reference server, whose data stream, once it sent DATA to a port, sends that port DATA as
fast as it can.
"""

from __future__ import annotations

import asyncio
import contextlib
import random
import select
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from rcmlconf.reference.drivers import choose_driver
from rcmlconf.reference.server.adapter import ReferenceServer, ServerSettings
from rcmlconf.rsp.codec import PacketType
from rcmlconf.rsp.codec.bodies import map_body
from rcmlconf.rsp.session.robot import RobotEndpoint
from rcmlconf.validate.validator import load_robot, load_robot_model

ROBOTS = Path(__file__).resolve().parents[2] / "rcmlconf" / "reference" / "robots"
CUBO = ROBOTS / "cubo" / "cubo.rmodel"
ROVER = ROBOTS / "rover" / "rover.rcml"
UPLINK, EMPTY = PacketType.UPLINK, map_body(())
#: Datagrams sent between two looks at the socket.
BURST = 50
#: Where a packet's first payload type is (D-RCTP-19: after the 16-byte header).
#: Ports flooded at once.
PORTS = 4
_FIRST_PAYLOAD, _DATA = 16, b"\x01"
#: Seconds a peer may take to say its port.
BOUND = 20.0


@contextlib.contextmanager
def flooding(*args: str) -> Iterator[int]:
    """The peer `args` name (`robot`, `robot --garbage`, `stream`) in a process of its own:
    its port. Killed at the end."""
    process = subprocess.Popen([sys.executable, __file__, *args], stdout=subprocess.PIPE, text=True)
    try:
        assert process.stdout is not None
        ready, _, _ = select.select([process.stdout], [], [], BOUND)
        line = process.stdout.readline() if ready else ""
        assert line.strip().isdigit(), f"the peer said no port ({line!r})"
        yield int(line)
    finally:
        process.kill()
        process.wait()


def robot(garbage: bool) -> None:
    endpoint = RobotEndpoint(load_robot_model(CUBO))
    sock, noise = socket.socket(type=socket.SOCK_DGRAM), socket.socket(type=socket.SOCK_DGRAM)
    with sock, noise:
        sock.bind(("127.0.0.1", 0))
        sock.setblocking(False)
        noise.setblocking(False)
        print(sock.getsockname()[1], flush=True)
        while True:
            now = time.monotonic()
            with contextlib.suppress(BlockingIOError):
                data, peer = sock.recvfrom(65536)
                endpoint.receive_datagram(data, peer, now)
            timer = endpoint.get_timer()
            if timer is not None and timer <= now:
                endpoint.handle_timer(now)
            for data, peer in endpoint.datagrams_to_send(now):
                sock.sendto(data, peer)
            session = endpoint.session
            if session is None:
                time.sleep(0.001)
                continue
            for _ in range(BURST):
                with contextlib.suppress(OSError):  # the peer's buffer full, or its socket closed
                    if garbage:
                        noise.sendto(random.randbytes(random.randrange(1, 64)), session.peer)
                    else:
                        uplink = session.wire.build(UPLINK, EMPTY, now, endpoint.free_buffers)
                        sock.sendto(uplink, session.peer)


class _Flooding:
    """The server's data socket: after its first DATA to a port, DATA to that port without end
    (to the last PORTS ports), the latest DATA sent again as fast as it can, each numbered one
    more (R-RCTP-41)."""

    def __init__(self, inner: Any) -> None:
        self.inner = inner
        self.sequence = 0
        self.latest: dict[object, bytes] = {}
        threading.Thread(target=self._flood, daemon=True).start()

    def sendto(self, data: bytes, addr: object = None) -> None:
        if data[_FIRST_PAYLOAD : _FIRST_PAYLOAD + 1] == _DATA:
            self.latest.pop(addr, None)
            self.latest[addr] = data
            while len(self.latest) > PORTS:
                del self.latest[next(iter(self.latest))]
        self._send(data, addr)

    def _send(self, data: bytes, addr: object) -> None:
        self.sequence = (self.sequence + 1) & 0xFFFF
        with contextlib.suppress(OSError):
            self.inner.sock.sendto(data[:2] + self.sequence.to_bytes(2, "big") + data[4:], addr)

    def _flood(self) -> None:
        while True:
            latest = list(self.latest.items())
            if not latest:
                time.sleep(0.01)
            for addr, data in latest:
                for _ in range(BURST):
                    self._send(data, addr)
            time.sleep(0)  # the server's own loop runs too

    def __getattr__(self, name: str) -> object:
        return getattr(self.inner, name)


async def stream() -> None:
    model = load_robot(ROVER)
    settings = ServerSettings(port=0, http_port=0)
    server = ReferenceServer(ROVER, model, choose_driver("auto", model), settings)
    await server.start()
    server._udp = _Flooding(server._udp)  # type: ignore[assignment]
    print(server.port, flush=True)
    await asyncio.Event().wait()


if __name__ == "__main__":
    if sys.argv[1] == "robot":
        robot("--garbage" in sys.argv)
    else:
        asyncio.run(stream())
