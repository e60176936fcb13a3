"""How many READ round trips a second does the reference server answer? (issue 5, "control")

The camera robot's `READ /status/lens` (an event access: its two readable nodes, a 29-byte body)
with the session's `Session`, one request at a time per connection, each sent when the answer to
the one before has arrived; on one connection and on 16. Anchor: a minimal HTTP/1.1 server of
h11 + asyncio (an `asyncio.Protocol`, as the reference server's control connections are) answering
`GET /status/lens` with a body of the same size, measured in the same run with the same client.

Each server runs in its own process, pinned to the first CPU (`os.sched_setaffinity`); the load
generator runs in this process, pinned to the last CPU: one asyncio loop, one lean
`asyncio.Protocol` per connection that frames each response by `Content-Length` and checks its
status is 200. The two servers and both connection counts are measured in turns, --reps rounds
of a --seconds window each (after a short warm-up); each figure is the median over the rounds.
The ratios, reference over anchor, are taken round by round (adjacent windows share the
machine's mood: it is shared and noisy, and the ratio is the figure that travels) and shown as
median and quartiles: of round trips/s (higher is better) and of the server's CPU time per round
trip (lower is better; less sensitive to noise, as time the server did not get is not counted).
Server and client CPU (/proc/PID/stat, `time.process_time`) show which side was the bottleneck.

    python bench/rctp_server_speed.py [--reps 15] [--seconds 0.75] [--profile]

--profile runs the reference server under cProfile and prints where its time went.
"""

from __future__ import annotations

import argparse
import asyncio
import cProfile
import functools
import os
import re
import signal
import statistics
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from multiprocessing.connection import Connection
from pathlib import Path

import h11
from children import Child, cpu_seconds, serve_camera, start_child, until_stopped

TARGET = "/status/lens"
CONNECTIONS = (1, 16)
WARM_UP = 0.3


# -- the servers (each in its own process) ----------------------------------------------------


class _HttpAnchor(asyncio.Protocol):
    """HTTP/1.1 with h11: every request is answered 200 with `body`."""

    def __init__(self, body: bytes) -> None:
        self.body = body
        self.conn = h11.Connection(h11.SERVER)
        self.transport: asyncio.Transport | None = None

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        assert isinstance(transport, asyncio.Transport)
        self.transport = transport

    def data_received(self, data: bytes) -> None:
        conn, transport = self.conn, self.transport
        assert transport is not None
        conn.receive_data(data)
        while True:
            event = conn.next_event()
            if event is h11.NEED_DATA or event is h11.PAUSED:
                return
            if isinstance(event, h11.EndOfMessage):
                headers = [
                    ("Content-Length", str(len(self.body))),
                    ("Content-Type", "application/rctp-values"),
                ]
                transport.write(
                    conn.send(h11.Response(status_code=200, headers=headers))
                    + conn.send(h11.Data(data=self.body))
                    + conn.send(h11.EndOfMessage())
                )
                conn.start_next_cycle()
            elif isinstance(event, h11.ConnectionClosed):
                transport.close()
                return

    def eof_received(self) -> bool:
        return False


async def _http_anchor(body_size: int, pipe: Connection, profiler: cProfile.Profile | None) -> None:
    """The anchor: h11 answering every request with a body of `body_size` bytes; tells
    (port, None, path) as `children.serve_camera` does."""
    loop = asyncio.get_running_loop()
    body = bytes(body_size)
    http = await loop.create_server(lambda: _HttpAnchor(body), "127.0.0.1", 0)
    pipe.send((http.sockets[0].getsockname()[1], None, "/"))
    try:
        await until_stopped(pipe, profiler)
    finally:
        http.close()


# -- the load generator -----------------------------------------------------------------------


class RoundTrips(asyncio.Protocol):
    """One connection sending a request each time the previous one's response has arrived."""

    def __init__(self, request: Callable[[int], bytes]) -> None:
        self.request = request
        self.number = 1
        self.buffer = bytearray()
        self.transport: asyncio.Transport | None = None
        self.loop = asyncio.get_running_loop()
        self.done: asyncio.Future[bytes] | None = None
        self.until = 0.0
        self.count = 0

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        assert isinstance(transport, asyncio.Transport)
        self.transport = transport

    def _send(self) -> None:
        assert self.transport is not None
        self.transport.write(self.request(self.number))
        self.number += 1

    def run(self, until: float) -> asyncio.Future[bytes]:
        """Round trips until loop time `until`; the future gives the last response."""
        self.done, self.until, self.count = self.loop.create_future(), until, 0
        self._send()
        return self.done

    def data_received(self, data: bytes) -> None:
        buffer = self.buffer
        buffer += data
        while (end := buffer.find(b"\r\n\r\n")) >= 0:
            start = buffer.lower().find(b"\r\ncontent-length:", 0, end)
            length = 0
            if start >= 0:
                stop = buffer.find(b"\r\n", start + 2)
                length = int(buffer[start + 17 : stop])
            total = end + 4 + length
            if len(buffer) < total:
                return
            response = bytes(buffer[:total])
            del buffer[:total]
            self._answered(response)

    def _answered(self, response: bytes) -> None:
        done = self.done
        if done is None or done.done():
            return
        if response[9:12] != b"200":
            done.set_exception(RuntimeError(f"not 200: {response[:200]!r}"))
        elif self.loop.time() < self.until:
            self.count += 1
            self._send()
        else:
            self.count += 1
            done.set_result(response)

    def connection_lost(self, exc: Exception | None) -> None:
        if self.done is not None and not self.done.done():
            self.done.set_exception(ConnectionError(f"connection lost: {exc}"))


def _connect(path: str, number: int) -> bytes:
    return f"CONNECT {path} RCTP/2.0\r\nCSeq: {number}\r\nUser-Agent: bench\r\n\r\n".encode()


def _read(session: str, number: int) -> bytes:
    return f"READ {TARGET} RCTP/2.0\r\nCSeq: {number}\r\nSession: {session}\r\n\r\n".encode()


def _get(number: int) -> bytes:
    return f"GET {TARGET} HTTP/1.1\r\nHost: 127.0.0.1\r\nX-CSeq: {number}\r\n\r\n".encode()


async def open_connections(server: Child, count: int) -> list[RoundTrips]:
    """RCTP connections with their session open (CONNECT), or HTTP connections."""
    loop = asyncio.get_running_loop()
    connections = []
    for _ in range(count):
        rctp = server.kind == "rctp"
        protocol = RoundTrips(functools.partial(_connect, server.ready[2]) if rctp else _get)
        await loop.create_connection(lambda p=protocol: p, "127.0.0.1", server.ready[0])  # type: ignore[misc]
        if rctp:
            answer = await asyncio.wait_for(protocol.run(0.0), 10)
            found = re.search(rb"\r\nSession: ([^;\r]+)", answer)
            assert found is not None, answer
            protocol.request = functools.partial(_read, found.group(1).decode())
        connections.append(protocol)
    return connections


@dataclass
class Window:
    per_second: float
    server_cpu: float
    client_cpu: float

    @property
    def cost(self) -> float:
        """Server CPU seconds per round trip."""
        return self.server_cpu / self.per_second if self.per_second else 0.0


async def window(server: Child, connections: list[RoundTrips], seconds: float) -> Window:
    loop = asyncio.get_running_loop()
    server_before, client_before = cpu_seconds(server.pid), time.process_time()
    start = loop.time()
    await asyncio.wait_for(
        asyncio.gather(*(c.run(start + seconds) for c in connections)), seconds + 30
    )
    elapsed = loop.time() - start
    count = sum(c.count for c in connections)
    return Window(
        count / elapsed,
        (cpu_seconds(server.pid) - server_before) / elapsed,
        (time.process_time() - client_before) / elapsed,
    )


async def response_sizes(servers: dict[str, Child]) -> dict[str, tuple[int, int]]:
    """(whole response, body) of each server's answer."""
    sizes = {}
    for kind, server in servers.items():
        (connection,) = await open_connections(server, 1)
        response = await asyncio.wait_for(connection.run(0.0), 10)
        sizes[kind] = (len(response), len(response) - response.index(b"\r\n\r\n") - 4)
        assert connection.transport is not None
        connection.transport.close()
    return sizes


async def measure(
    servers: dict[str, Child], reps: int, seconds: float
) -> dict[tuple[str, int], list[Window]]:
    results: dict[tuple[str, int], list[Window]] = {}
    connections = {
        (kind, count): await open_connections(server, count)
        for kind, server in servers.items()
        for count in CONNECTIONS
    }
    for (kind, _count), opened in connections.items():
        await window(servers[kind], opened, WARM_UP)
    for rep in range(reps):
        kinds = list(servers) if rep % 2 == 0 else list(reversed(servers))
        for count in CONNECTIONS:
            for kind in kinds:
                result = await window(servers[kind], connections[kind, count], seconds)
                results.setdefault((kind, count), []).append(result)
    for opened in connections.values():
        for connection in opened:
            if connection.transport is not None:
                connection.transport.close()
    return results


def spread(ratios: list[float]) -> str:
    """The median ratio and its quartiles."""
    if len(ratios) < 2:
        return f"{ratios[0]:.2f}x" if ratios else "-"
    low, middle, high = statistics.quantiles(ratios, n=4)
    return f"{middle:.2f}x (quartiles {low:.2f}-{high:.2f})"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--reps", type=int, default=15)
    parser.add_argument("--seconds", type=float, default=0.75)
    parser.add_argument("--profile", action="store_true", help="profile the reference server")
    args = parser.parse_args()
    # A termination unwinds like Ctrl-C does, through the `finally`s that stop the children.
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))
    cpus = sorted(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else []
    server_cpu = cpus[0] if len(cpus) > 1 else None
    if len(cpus) > 1:
        os.sched_setaffinity(0, {cpus[-1]})
    servers: dict[str, Child] = {}
    profile = None
    try:
        servers["rctp"] = start_child(
            "rctp", serve_camera, server_cpu, "rcmlconf" if args.profile else None
        )
        body = asyncio.run(response_sizes(servers))["rctp"][1]
        servers["http"] = start_child(  # the same body size
            "http", functools.partial(_http_anchor, body), server_cpu
        )
        sizes = asyncio.run(response_sizes(servers))
        results = asyncio.run(measure(servers, args.reps, args.seconds))
    finally:
        for kind in list(servers):
            report = servers.pop(kind).stop()
            profile = report or profile
    where = (
        f"servers on CPU {server_cpu}, load generator on CPU {cpus[-1]}"
        if server_cpu is not None
        else "one CPU: server and load generator share it"
    )
    load = Path("/proc/loadavg").read_text().split()[0] if Path("/proc/loadavg").exists() else "?"
    print(
        f"READ {TARGET} round trips, one request at a time per connection; median of"
        f" {args.reps} windows of {args.seconds:g} s"
    )
    print(
        f"{where}; response {sizes['rctp'][0]} B (RCTP) / {sizes['http'][0]} B (HTTP),"
        f" body {sizes['rctp'][1]} B both; load average {load}"
    )
    labels = {"http": "h11 + asyncio HTTP/1.1 (anchor)", "rctp": "rcmlconf reference server"}
    print(
        f"{'conns':>5}  {'server':<32} {'round trips/s':>13} {'server CPU':>10}"
        f" {'client CPU':>10} {'CPU/round trip':>14}"
    )
    for count in CONNECTIONS:
        for kind in ("http", "rctp"):
            rows = results[kind, count]
            print(
                f"{count:>5}  {labels[kind]:<32}"
                f" {statistics.median(r.per_second for r in rows):>13,.0f}"
                f" {statistics.median(r.server_cpu for r in rows):>10.0%}"
                f" {statistics.median(r.client_cpu for r in rows):>10.0%}"
                f" {statistics.median(r.cost for r in rows) * 1e6:>11.0f} µs"
            )
        pairs = list(zip(results["rctp", count], results["http", count], strict=True))
        speed = spread([r.per_second / a.per_second for r, a in pairs])
        cost = spread([r.cost / a.cost for r, a in pairs if a.cost])
        print(f"{'':>5}  reference / anchor, round by round: round trips/s {speed}; CPU {cost}")
    if profile:
        print("\n(with --profile, the reference server's figures above are slowed by cProfile)")
        print("the reference server under cProfile (whole run), by own time:")
        print(profile)


if __name__ == "__main__":
    try:
        main()
    except KeyboardInterrupt:
        sys.exit("interrupted")
