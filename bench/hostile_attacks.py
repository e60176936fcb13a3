"""The attackers of bench/hostile_load.py, in a process of their own, on raw sockets.

Each attack comes from source addresses of its own in 127/8, never 127.0.0.1 (Linux's loopback
takes any of them): the server's per-address caps (D-RCTP-32) then tell the attackers from the
legitimate clients on 127.0.0.1, as addresses do on a real network. Every loop ends at the
attack's deadline; every socket is closed with a reset (SO_LINGER 0), so that tens of thousands
of short connections leave no TIME_WAIT behind to run the ports out. The process is niced, so
that on a shared machine the legitimate clients beside it are woken first; its CPU time is
reported with its counts.

Only the standard library: the process starts fast and measures nothing but what it did.
"""

from __future__ import annotations

import asyncio
import contextlib
import os
import random
import re
import resource
import socket
import struct
import time
from collections import Counter
from collections.abc import Callable, Coroutine
from dataclasses import dataclass
from multiprocessing.connection import Connection
from typing import Any

#: Linux's IP_BIND_ADDRESS_NO_PORT: the port is chosen at connect(), by the whole 4-tuple.
IP_BIND_ADDRESS_NO_PORT = getattr(socket, "IP_BIND_ADDRESS_NO_PORT", 24)
NICE = 10

SLOWLORIS_CONNECTIONS = 1000
PIPELINED_REQUESTS = 20_000
CONNECT_FLOOD = 3000
IDLE_FLOOD = 1100
MALFORMED_WORKERS = 8
BIG_BODY = 4 << 20
BIG_HEADER = 256 << 10
UDP_RATE = 10_000  # datagrams a second
UDP_TICK = 0.01

#: Each attack's source addresses (the slowloris's 1,000 connections are 250 an address, the
#: idle flood's 1,100 are 220, under the default cap of 256 an address: what must close them is
#: the slow timeout, or a full table making room, D-RCTP-32).
SOURCES: dict[str, tuple[str, ...]] = {
    "slowloris": ("127.0.0.2", "127.0.0.3", "127.0.0.4", "127.0.0.5"),
    "pipelining": ("127.0.0.6",),
    "malformed": ("127.0.0.7",),
    "connect-flood": ("127.0.0.8", "127.0.0.9", "127.0.0.10"),
    "udp": ("127.0.0.11",),
    "idle-flood": ("127.0.0.12", "127.0.0.13", "127.0.0.14", "127.0.0.15", "127.0.0.16"),
}
ATTACKS = tuple(SOURCES)
#: The mix: issue 18's five attacks at once (the idle flood is judged in its own row).
MIXED = ("slowloris", "pipelining", "malformed", "connect-flood", "udp")


@dataclass(frozen=True)
class Target:
    rctp_port: int
    http_port: int
    data_port: int
    #: The robot's site path (CONNECT's target) and a data node to READ.
    site: str
    node: str


class Attack:
    """What one attack shares: the target, the deadline, the counts."""

    def __init__(self, target: Target, deadline: float) -> None:
        self.target = target
        self.deadline = deadline
        self.loop = asyncio.get_running_loop()
        self.counts: Counter[str] = Counter()

    def left(self) -> float:
        return self.deadline - self.loop.time()

    async def sleep(self, seconds: float) -> None:
        await asyncio.sleep(max(0.0, min(seconds, self.left())))

    async def connect(self, source: str, port: int, timeout: float = 2.0) -> socket.socket | None:
        """A TCP connection from `source` to the server's `port`, or None (counted)."""
        sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        sock.setblocking(False)
        sock.setsockopt(socket.SOL_IP, IP_BIND_ADDRESS_NO_PORT, 1)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
        try:
            sock.bind((source, 0))
            wait = max(0.01, min(timeout, self.left()))
            await asyncio.wait_for(self.loop.sock_connect(sock, ("127.0.0.1", port)), wait)
        except (OSError, TimeoutError):
            sock.close()
            self.counts["connect failed"] += 1
            return None
        self.counts["connections"] += 1
        return sock

    async def send(self, sock: socket.socket, data: bytes, timeout: float = 5.0) -> None:
        wait = max(0.01, min(timeout, self.left()))
        await asyncio.wait_for(self.loop.sock_sendall(sock, data), wait)

    async def receive(self, sock: socket.socket, timeout: float = 2.0) -> bytes:
        wait = max(0.01, min(timeout, self.left()))
        return await asyncio.wait_for(self.loop.sock_recv(sock, 65536), wait)


def _connect_request(site: str, cseq: int = 1) -> bytes:
    return f"CONNECT {site} RCTP/2.0\r\nCSeq: {cseq}\r\n\r\n".encode()


# -- slowloris: 1,000 connections, a byte now and then -----------------------------------------


async def slowloris(attack: Attack) -> None:
    sources = SOURCES["slowloris"]
    each = SLOWLORIS_CONNECTIONS // len(sources)
    await asyncio.gather(
        *(_loris(attack, source, index % 2 == 1) for source in sources for index in range(each))
    )


async def _loris(attack: Attack, source: str, with_session: bool) -> None:
    """Half the connections CONNECT first (a session, or 503 beyond the cap an address) and then
    never finish a request; the others never send a whole request at all."""
    target = attack.target
    head = f"READ {target.node} RCTP/2.0\r\nCSeq: 2\r\nX-Slow: ".encode()
    while attack.left() > 0:
        sock = await attack.connect(source, target.rctp_port)
        if sock is None:
            await attack.sleep(0.5)
            continue
        try:
            if with_session:
                await attack.send(sock, _connect_request(target.site))
            await attack.sleep(random.uniform(0.0, 1.0))  # not all in step
            sent = 0
            while attack.left() > 0:
                await attack.send(sock, head[sent : sent + 1] or b"a")
                sent += 1
                attack.counts["bytes dribbled"] += 1
                await attack.sleep(random.uniform(0.5, 2.0))
        except (OSError, TimeoutError):
            attack.counts["closed by the server"] += 1
        finally:
            sock.close()


# -- pipelining: 20,000 READs on one connection, without and with CONNECT ----------------------

_CSEQ = re.compile(rb"\r\nCSeq: (\d+)\r\n")


async def pipelining(attack: Attack) -> None:
    with_session = False
    while attack.left() > 0:
        await _burst(attack, with_session)
        with_session = not with_session


async def _burst(attack: Attack, with_session: bool) -> None:
    target = attack.target
    sock = await attack.connect(SOURCES["pipelining"][0], target.rctp_port)
    if sock is None:
        await attack.sleep(0.5)
        return
    try:
        session = b""
        if with_session:
            await attack.send(sock, _connect_request(target.site))
            answer = await attack.receive(sock)
            found = re.search(rb"Session: ([0-9a-f]+)", answer)
            session = b"Session: " + found.group(1) + b"\r\n" if found else b""
        line = f"READ {target.node} RCTP/2.0\r\n".encode()
        first = 2
        burst = b"".join(
            line + b"CSeq: %d\r\n" % cseq + session + b"\r\n"
            for cseq in range(first, first + PIPELINED_REQUESTS)
        )
        counting = asyncio.ensure_future(_count_answers(attack, sock, first))
        await attack.send(sock, burst, timeout=60.0)
        attack.counts["requests pipelined"] += PIPELINED_REQUESTS
        answered, in_order = await counting
        attack.counts["answers"] += answered
        kind = "with CONNECT" if with_session else "without CONNECT"
        whole = answered == PIPELINED_REQUESTS and in_order
        attack.counts[f"bursts {kind} answered {'whole, in order' if whole else 'short'}"] += 1
    except (OSError, TimeoutError):
        attack.counts["bursts broken off"] += 1
    finally:
        sock.close()


async def _count_answers(attack: Attack, sock: socket.socket, first: int) -> tuple[int, bool]:
    """How many answers came, until all of them, the close or the deadline; and whether their
    CSeqs came in order (R-RCTP-13)."""
    answered, expected, in_order = 0, first, True
    pending = b""
    with contextlib.suppress(OSError, TimeoutError):
        while answered < PIPELINED_REQUESTS and attack.left() > 0:
            data = await attack.receive(sock, timeout=10.0)
            if not data:
                break
            pending += data
            cut = pending.rfind(b"\r\n\r\n")
            if cut < 0:
                continue
            for found in _CSEQ.finditer(pending, 0, cut + 2):
                in_order = in_order and int(found.group(1)) == expected
                expected += 1
                answered += 1
            pending = pending[cut + 2 :]
    return answered, in_order


# -- malformed: bad request lines, oversized heads, 4 MiB bodies, on RCTP and HTTP -------------


def _malformed(target: Target) -> tuple[tuple[str, int, bytes], ...]:
    big = b"a" * BIG_HEADER
    body = bytes(BIG_BODY)
    node = target.node.encode()
    return (
        ("RCTP bad request line", target.rctp_port, b"GARBAGE \x00\xff\xfe nonsense\r\n\r\n"),
        (
            "RCTP 256 KiB header",
            target.rctp_port,
            b"READ " + node + b" RCTP/2.0\r\nCSeq: 1\r\nX-Big: " + big + b"\r\n\r\n",
        ),
        (
            "RCTP 4 MiB body",
            target.rctp_port,
            _connect_request(target.site)[:-2] + b"Content-Length: %d\r\n\r\n" % BIG_BODY + body,
        ),
        ("HTTP bad request line", target.http_port, b"GARBAGE \x00\xff\r\n\r\n"),
        (
            "HTTP 256 KiB header",
            target.http_port,
            b"GET / HTTP/1.1\r\nHost: x\r\nX-Big: " + big + b"\r\n\r\n",
        ),
        (
            "HTTP 4 MiB body",
            target.http_port,
            b"POST / HTTP/1.1\r\nHost: x\r\nContent-Length: %d\r\n\r\n" % BIG_BODY + body,
        ),
    )


async def malformed(attack: Attack) -> None:
    kinds = _malformed(attack.target)
    await asyncio.gather(*(_malform(attack, kinds, w) for w in range(MALFORMED_WORKERS)))


async def _malform(attack: Attack, kinds: tuple[tuple[str, int, bytes], ...], start: int) -> None:
    turn = start
    while attack.left() > 0:
        what, port, request = kinds[turn % len(kinds)]
        turn += 1
        sock = await attack.connect(SOURCES["malformed"][0], port)
        if sock is None:
            await attack.sleep(0.2)
            continue
        try:
            await attack.send(sock, request)
            attack.counts[what] += 1
            answer = await attack.receive(sock)
            attack.counts["answered" if answer else "closed unanswered"] += 1
        except (OSError, TimeoutError):
            attack.counts["cut off by the server"] += 1
        finally:
            sock.close()


# -- connect flood: waves of 3,000 connections that each CONNECT -------------------------------


async def connect_flood(attack: Attack) -> None:
    sources = SOURCES["connect-flood"]
    each = CONNECT_FLOOD // len(sources)
    while attack.left() > 0:
        await asyncio.gather(*(_knock(attack, s) for s in sources for _ in range(each)))
        attack.counts["waves"] += 1


async def _knock(attack: Attack, source: str) -> None:
    sock = await attack.connect(source, attack.target.rctp_port)
    if sock is None:
        return
    try:
        await attack.send(sock, _connect_request(attack.target.site))
        answer = await attack.receive(sock)
        status = answer[9:12].decode("ascii", "replace") if answer else "closed at once"
        attack.counts[f"CONNECT {status}"] += 1
    except (OSError, TimeoutError):
        attack.counts["CONNECT closed at once"] += 1
    finally:
        sock.close()


# -- idle flood: 1,100 connections that send nothing, opened again as soon as they are closed --


async def idle_flood(attack: Attack) -> None:
    sources = SOURCES["idle-flood"]
    each = IDLE_FLOOD // len(sources)
    await asyncio.gather(*(_idle(attack, source) for source in sources for _ in range(each)))


async def _idle(attack: Attack, source: str) -> None:
    """A connection that sends nothing; once the server closes it, another at once."""
    while attack.left() > 0:
        sock = await attack.connect(source, attack.target.rctp_port)
        if sock is None:
            await attack.sleep(0.05)
            continue
        try:
            while await attack.receive(sock, timeout=attack.left()):
                pass
            attack.counts["closed by the server"] += 1
        except TimeoutError:
            pass  # the deadline
        except OSError:
            attack.counts["reset by the server"] += 1
        finally:
            sock.close()


# -- garbage UDP at the data port --------------------------------------------------------------


def _garbage(count: int) -> list[bytes]:
    """Random datagrams: a third random bytes, the rest headed like RCTP data-stream packets
    (version 2, a random tag) with random payloads."""
    made = []
    for index in range(count):
        size = random.randrange(1, 1400)
        junk = random.randbytes(size)
        if index % 3:
            head = struct.pack(">BBHIQ", 2, random.randrange(1, 8), 0, random.getrandbits(32), 0)
            junk = head + junk
        made.append(junk)
    return made


async def udp(attack: Attack) -> None:
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.setblocking(False)
    sock.bind((SOURCES["udp"][0], 0))
    datagrams = _garbage(512)
    address = ("127.0.0.1", attack.target.data_port)
    batch = int(UDP_RATE * UDP_TICK)
    turn = 0
    try:
        while attack.left() > 0:
            for _ in range(batch):
                try:
                    sock.sendto(datagrams[turn % len(datagrams)], address)
                    attack.counts["datagrams"] += 1
                except BlockingIOError:
                    attack.counts["datagrams not sent (buffer full)"] += 1
                except OSError:  # an ICMP error of an earlier one
                    attack.counts["send errors"] += 1
                turn += 1
            await attack.sleep(UDP_TICK)
    finally:
        sock.close()


RUNS: dict[str, Callable[[Attack], Coroutine[Any, Any, None]]] = {
    "slowloris": slowloris,
    "pipelining": pipelining,
    "malformed": malformed,
    "connect-flood": connect_flood,
    "udp": udp,
    "idle-flood": idle_flood,
}


# -- the process -------------------------------------------------------------------------------


async def _attack(names: tuple[str, ...], target: Target, seconds: float, pipe: Connection) -> None:
    loop = asyncio.get_running_loop()
    deadline = loop.time() + seconds
    attacks = {name: Attack(target, deadline) for name in names}
    pipe.send(("started", time.monotonic()))
    cpu = time.process_time()
    # Bounded twice: each loop stops at the deadline, and what is left is cancelled after it.
    tasks = [asyncio.ensure_future(RUNS[name](attacks[name])) for name in names]
    _done, late = await asyncio.wait(tasks, timeout=seconds + 15.0)
    for task in late:
        task.cancel()
    with contextlib.suppress(asyncio.CancelledError):
        await asyncio.gather(*late, return_exceptions=True)
    ended = time.monotonic()
    counts = {name: dict(attack.counts) for name, attack in attacks.items()}
    pipe.send(("done", ended, time.process_time() - cpu, counts))


def attack_process(
    names: tuple[str, ...], target: Target, seconds: float, cpu: int | None, pipe: Connection
) -> None:
    """The attacks `names` for `seconds`, all at once, from this (spawned) process; tells the
    parent when they started and, at the end, when they ended, its CPU time and the counts."""
    os.nice(NICE)
    if cpu is not None:
        os.sched_setaffinity(0, {cpu})
    _soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    with contextlib.suppress(ValueError, OSError):
        resource.setrlimit(resource.RLIMIT_NOFILE, (hard, hard))
    with contextlib.suppress(KeyboardInterrupt):
        asyncio.run(_attack(names, target, seconds, pipe))
    pipe.close()
