"""How many RSP robot/local pairs at T = 20 ms does one core hold? (issue: "pairs")

N pairs, each a `ReferenceRobot` (CUBO, specs/rsp.md D-RSP-8, with a `GenericBody`) and a
`Simulacrum` in a session at the model's T = 20 ms: the base module active, leftWheel and
rightWheel written (a 28-byte DOWNLINK every T), the position sensor requested (a 36-byte UPLINK
every T). The figure is the largest N whose p99 period jitter is <= 2 ms, nothing lost; goal:
N >= 200.

How: both sides of every pair ("on one core") run on one asyncio loop in one process pinned to the
first CPU (`os.sched_setaffinity`), a fresh one for each N; this process, the measurer, is pinned
to the last CPU. RSP runs on either adapter of `rcmlconf.reference` (--adapter; both by default,
each its own row): `asyncio`, a datagram transport and a loop timer per endpoint; `batch`
(`reference.rsp.batch`), every endpoint's socket read from one epoll set and every timer on one
clock of a loop timer per millisecond. Every endpoint has a socket of its own either way (D-RSP-9).
Once set up, the measured process freezes what it made out of the garbage collector's way
(`gc.freeze`), the anchor's too: each full collection would otherwise walk it, a pause of
milliseconds. The pairs start at random times over max(T, N x 0.5 ms), rounded up to whole
periods (each robot just before its simulacrum opens the session), so that their beats and
control ticks are spread over the period as independent robots' would be.

Jitter is |interval between one session's consecutive DOWNLINKs at the robot - 20 ms|, and the
same for UPLINKs at the simulacrum, over all sessions after --warm-up, for --seconds (p50, p99,
max). It is taken from the kernel's receive stamps: the measurer reads every UDP packet of the
loopback interface from a packet socket (AF_PACKET, SO_TIMESTAMPNS, incoming only, cut to the
RSP header's first bytes by a socket filter), drained every 2 ms without waiting in epoll (which
would cost each of the measured process's sendto a wake-up). On loopback a packet is stamped in
its sender's sendto, as it enters the receiver's socket buffer: these are the instants the
packets reached the robot and the simulacrum, independent of when the measured process got round
to reading them, so the jitter is the senders' beats, not the receivers' lateness. A packet socket
needs CAP_NET_RAW; without it (or with --stamps process) the stamps are the measured process's
own, below.

The measured process also stamps every packet on receipt (its loop's clock, in the robot's
`datagram_received` and the simulacrum's `received`, before either handles it) with its type and
sequence number: `seen` is the jitter by those stamps, what the robot and the simulacrum saw,
their own delay in reading included; `lost`, the gaps in each session's sequence numbers at its
receiver (a socket buffer that overflowed shows up there); `silent`, pairs of which a side
received nothing; `rate`, the DOWNLINKs and UPLINKs counted over 2 N per 20 ms (beats skipped by
a sender that fell behind lower it). CPU, from /proc over the window: the measured process's,
and its CPU time per pair and period served (`µs/pair`: per DOWNLINK and UPLINK that went out,
the robot's control ticks included); what other processes and the hypervisor (`steal`) took of
its CPU; the measurer's. A row that fails is run again, up to --tries runs, and the best is
shown: the machine is shared, and its noise only adds jitter. An RSP row that fails by jitter
alone, where the anchor failed too with a p99 not much lower (1.5 times), is `noisy`. N goes up
the list, each adapter until its row FAILs (--keep-going, --quick: every N); the last lines say,
for each adapter, at which N the pairs' CPU time fills one core, jitter aside.

Floor, in the same run and for each N: RSP's own work for N pairs, in memory, on the same CPU
(`_core_floor`: the endpoints, the robot's control tick and body, with no socket, loop or timer);
with the kernel's cost of a loopback datagram (about 6 µs to send and read one here) it is what no
adapter can go below. The ratios line gives each adapter's µs per pair and period, and CPU, to the
anchor's, and µs per pair and period to the floor's.

Anchor, in the same run and for each N: a minimal asyncio pair in RSP's place (one process on the
same CPU; per pair two UDP sockets, bare `asyncio.DatagramProtocol`s, each side sending its
packet, of RSP's size and with RSP's type and sequence number, every 20 ms on the beat with
`loop.call_at`; received packets are stamped and dropped): what the machine and asyncio allow.

    python bench/rsp_pairs_scale.py [--max-n 1000] [--seconds 8] [--warm-up 2] [--tries 3]
    python bench/rsp_pairs_scale.py --quick            # N = 50 and 200, 2 s each, one run each
    python bench/rsp_pairs_scale.py --json             # the table on stderr, JSON on stdout
    python bench/rsp_pairs_scale.py --adapter batch    # the batch adapter only
    python bench/rsp_pairs_scale.py --profile 200      # the RSP process under cProfile, N = 200
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import cProfile
import ctypes
import functools
import gc
import json
import math
import random
import signal
import socket
import struct
import sys
import time
from array import array
from bisect import bisect_left
from collections.abc import Awaitable, Callable
from dataclasses import dataclass, field
from multiprocessing.connection import Connection
from typing import Any, TextIO, cast

from children import ROOT, Child, start_child, until_stopped
from scale import (
    MIN_RATE,
    SO_TIMESTAMPNS,
    Usage,
    UsageProbe,
    best_of,
    load_average,
    percentile,
    split_cpus,
    stamp_ns,
    steps,
    verdict,
)

CUBO = ROOT / "rcmlconf" / "reference" / "robots" / "cubo" / "cubo.rmodel"
PERIOD = 0.020
PERIOD_NS = 20_000_000
GOAL_N = 200
MAX_JITTER_MS = 2.0
#: An RSP row failed by jitter alone is `noisy` where the anchor failed too, with a p99 at most
#: this many times the anchor's.
NOISY = 1.5
STEPS = (50, 100, 200, 300, 400, 500, 600, 800, 1000)
#: Pairs start at random times over N times this (a period at least, in whole periods).
START_EVERY = 0.0005
#: D-RSP-11's packet types, and the sizes of this bench's packets (CUBO: a 4-byte Device Map;
#: two int16 wheel speeds down, three float32 of position up), which the anchor sends.
DOWNLINK, UPLINK = 4, 5
SIZES = {DOWNLINK: 28, UPLINK: 36}
#: The measurer sleeps this long between draining its packet socket (see the docstring).
POLL_EVERY = 0.002
#: The floor (`_core_floor`) runs this long, CPU seconds.
FLOOR_SECONDS = 2.0
#: Setting up the sessions, and sending back the stamps, may take this long at most.
SETUP_TIMEOUT = 120.0

# The packet socket (Linux): loopback, IPv4, incoming only, cut by a socket filter.
ETH_P_IP = 0x0800
SOL_PACKET = 263
PACKET_STATISTICS = 6
PACKET_IGNORE_OUTGOING = 23
SO_ATTACH_FILTER = 26
SO_RCVBUFFORCE = 33
SNIFF_BUFFER = 32 << 20
#: What is kept of a packet: IPv4 and UDP headers and RSP's version, model ID, encryption, type
#: and sequence number (20 + 8 + 7 bytes without IP options), and room for IP options.
SNAP = 64
#: Classic BPF: UDP (IP protocol 17) kept, cut to SNAP bytes; anything else dropped.
UDP_ONLY = ((0x30, 0, 0, 9), (0x15, 0, 1, 17), (0x06, 0, 0, SNAP), (0x06, 0, 0, 0))


# -- the measured process ---------------------------------------------------------------------


class Arrivals:
    """What one socket of the measured process received: when (the loop's clock, time.monotonic,
    on receipt), and each packet's type and sequence number as `type << 16 | sequence`."""

    __slots__ = ("marks", "times")

    def __init__(self) -> None:
        self.times = array("d")
        self.marks = array("I")

    def add(self, data: bytes) -> None:
        self.times.append(time.monotonic())
        self.marks.append(int.from_bytes(data[4:7], "big") if len(data) >= 7 else 0)

    def between(self, start: float, end: float) -> tuple[array[float], array[int]]:
        first, last = bisect_left(self.times, start), bisect_left(self.times, end)
        return self.times[first:last], self.marks[first:last]


Pairs = list[tuple[int, int]]  # (robot port, local port) of each pair
Seen = list[tuple[Arrivals, Arrivals]]  # (at the robot, at the local side) of each pair


def spread(n: int) -> float:
    """How long the pairs take to start: max(T, N x START_EVERY), in whole periods."""
    return PERIOD * max(1, -(-n * START_EVERY // PERIOD))


async def _measured(
    pipe: Connection,
    profiler: cProfile.Profile | None,
    start_pairs: Callable[[int], Awaitable[tuple[Pairs, Seen]]],
    close: Callable[[], Awaitable[None]],
) -> None:
    """The measured process's part: ready; N from the parent; the pairs started and their ports
    told; until the parent sends the window (or stops it), what was received in the window."""
    pipe.send(())
    n: int = pipe.recv()
    pairs, seen = await start_pairs(n)
    # What setup made lives as long as the pairs: out of the collector's way, or every full
    # collection walks it, a pause of milliseconds that the beats due meanwhile wait out.
    gc.freeze()
    pipe.send(pairs)
    await until_stopped(pipe, profiler)
    window = None
    with contextlib.suppress(EOFError, OSError):
        window = pipe.recv() if pipe.poll(0) else None
    await close()
    if isinstance(window, tuple):
        start, end = window
        with contextlib.suppress(OSError):
            pipe.send([(r.between(start, end), s.between(start, end)) for r, s in seen])


async def _rsp_pairs(
    pipe: Connection, profiler: cProfile.Profile | None, batched: bool = False
) -> None:
    """N ReferenceRobots and N Simulacrums, each pair in a session: wheels down, position up;
    each endpoint on asyncio's transport and timer, or all on one `Batch` (`batched`)."""
    from rcmlconf.reference.rsp.batch import Batch
    from rcmlconf.reference.rsp.bodies import GenericBody
    from rcmlconf.reference.rsp.robot import ReferenceRobot, RobotSettings
    from rcmlconf.reference.rsp.simulacrum import Simulacrum
    from rcmlconf.validate.validator import load_robot_model

    model = load_robot_model(CUBO)
    robots: list[ReferenceRobot] = []
    simulacrums: list[Simulacrum] = []
    batch = Batch(asyncio.get_running_loop()) if batched else None

    async def start_pair(delay: float) -> tuple[tuple[int, int], tuple[Arrivals, Arrivals]]:
        await asyncio.sleep(delay)
        at_robot, at_local = Arrivals(), Arrivals()
        robot = ReferenceRobot(model, RobotSettings(port=0), body=GenericBody(model))
        received = robot.datagram_received

        def robot_received(data: bytes, addr: tuple[str, int]) -> None:
            at_robot.add(data)
            received(data, addr)

        robot.datagram_received = robot_received  # type: ignore[method-assign]
        await robot.start(batch)
        robots.append(robot)
        local = Simulacrum(model, robot.address)
        local_received = local.received

        def local_got(data: bytes) -> None:
            at_local.add(data)
            local_received(data)

        local.received = local_got  # type: ignore[method-assign]
        simulacrums.append(local)
        await local.open(timeout=SETUP_TIMEOUT, batch=batch)
        local.set_active("base", True)
        local.write("leftWheel", {"speed": 120})
        local.write("rightWheel", {"speed": -80})
        local.set_active("position", True)
        session = robot.endpoint.session
        assert session is not None
        return (robot.address[1], session.peer[1]), (at_robot, at_local)

    async def start_pairs(n: int) -> tuple[Pairs, Seen]:
        window = spread(n)
        started = await asyncio.gather(*(start_pair(random.uniform(0, window)) for _ in range(n)))
        return [ports for ports, _ in started], [seen for _, seen in started]

    async def close() -> None:
        for local in simulacrums:
            await local.aclose()
        await asyncio.sleep(0.05)
        for robot in robots:
            robot.stop()
        if batch is not None:
            batch.close()

    await _measured(pipe, profiler, start_pairs, close)


#: What runs each side of the bench (`run`): RSP on either adapter, and the anchor.
MAINS = {
    "asyncio": _rsp_pairs,
    "batch": functools.partial(_rsp_pairs, batched=True),
}


class _Side(asyncio.DatagramProtocol):
    """One side of an anchor pair: every packet stamped and dropped; its own packet every T."""

    def __init__(self, arrivals: Arrivals, kind: int) -> None:
        self.arrivals = arrivals
        self.transport: asyncio.DatagramTransport | None = None
        self.to: tuple[str, int] | None = None
        self.head = bytes([1, 0, 1, 0, kind])
        self.tail = bytes(SIZES[kind] - 7)
        self.sequence = 0
        self.sending = True

    def itself(self) -> _Side:
        """The protocol factory of its endpoint."""
        return self

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        self.transport = cast(asyncio.DatagramTransport, transport)

    def datagram_received(self, data: bytes, addr: tuple[str, int]) -> None:
        self.arrivals.add(data)

    def beat(self, due: float) -> None:
        if not self.sending or self.transport is None:
            return
        loop = asyncio.get_running_loop()
        now = loop.time()
        packet = self.head + self.sequence.to_bytes(2, "big") + self.tail
        self.transport.sendto(packet, self.to)
        self.sequence = (self.sequence + 1) & 0xFFFF
        after = due + PERIOD
        after = after if after > now else now + PERIOD  # no burst to make up missed beats
        loop.call_at(after, self.beat, after)


async def _anchor_pairs(pipe: Connection, profiler: cProfile.Profile | None) -> None:
    """N pairs of bare asyncio UDP sockets, each side sending RSP's packet every 20 ms."""
    loop = asyncio.get_running_loop()
    sides: list[_Side] = []

    async def start_pairs(n: int) -> tuple[Pairs, Seen]:
        pairs: Pairs = []
        seen: Seen = []
        for _ in range(n):
            at_robot, at_local = Arrivals(), Arrivals()
            robot = _Side(at_robot, UPLINK)
            local = _Side(at_local, DOWNLINK)
            await loop.create_datagram_endpoint(robot.itself, local_addr=("127.0.0.1", 0))
            assert robot.transport is not None
            address = robot.transport.get_extra_info("sockname")[:2]
            await loop.create_datagram_endpoint(local.itself, remote_addr=address)
            assert local.transport is not None
            robot.to = local.transport.get_extra_info("sockname")[:2]
            sides.extend((robot, local))
            pairs.append((address[1], robot.to[1]))
            seen.append((at_robot, at_local))
        start = loop.time()
        for pair in range(n):
            first = start + random.uniform(0, spread(n))
            for side in sides[2 * pair : 2 * pair + 2]:
                loop.call_at(first, side.beat, first)
        return pairs, seen

    async def close() -> None:
        for side in sides:
            side.sending = False
            if side.transport is not None:
                side.transport.close()

    await _measured(pipe, profiler, start_pairs, close)


async def _core_floor(pipe: Connection, profiler: cProfile.Profile | None) -> None:
    """The floor: RSP's own work for N pairs a period, in memory, with no socket, loop or timer.
    Each period, pair after pair as the beats come in the bench: the local system's DOWNLINK, the
    robot reading it, the robot's control tick (`ReferenceRobot._control_tick`, its body) and its
    UPLINK, the local system reading that. Sends (µs of CPU per pair and period, the periods)."""
    from rcmlconf.reference.rsp.bodies import GenericBody
    from rcmlconf.reference.rsp.robot import ReferenceRobot, RobotSettings
    from rcmlconf.rsp.session.local import LocalEndpoint
    from rcmlconf.validate.validator import load_robot_model

    model = load_robot_model(CUBO)
    pipe.send(())
    n: int = pipe.recv()
    pairs = []
    for index in range(n):
        robot = ReferenceRobot(model, RobotSettings(port=0), body=GenericBody(model))
        local, peer = LocalEndpoint(model), ("127.0.0.1", 1024 + index)
        local.connect(0.0)
        for data in local.datagrams_to_send(0.0):
            robot.endpoint.receive_datagram(data, peer, 0.0)
        for data, _ in robot.endpoint.datagrams_to_send(0.0):
            local.receive_datagram(data, 0.0)
        local.set_active("base", True)
        local.write("leftWheel", {"speed": 120})
        local.write("rightWheel", {"speed": -80})
        local.set_active("position", True)
        pairs.append((robot, local, peer))
    periods = 0
    start = time.process_time()
    while time.process_time() - start < FLOOR_SECONDS:
        periods += 1
        now = periods * (PERIOD + 1e-6)  # a hair over T: every beat due, whatever the rounding
        for robot, local, peer in pairs:
            endpoint = robot.endpoint
            local.handle_timer(now)
            for data in local.datagrams_to_send(now):
                endpoint.receive_datagram(data, peer, now)
            while local.next_event() is not None or endpoint.next_event() is not None:
                pass
            robot._control_tick(now)
            endpoint.handle_timer(now)
            for data, _ in endpoint.datagrams_to_send(now):
                local.receive_datagram(data, now)
            while local.next_event() is not None or endpoint.next_event() is not None:
                pass
            local.get_timer()
            endpoint.get_timer()
    cost = (time.process_time() - start) / (periods * n)
    sent = sum(local.packets_sent for _, local, _ in pairs)
    assert sent >= periods * n, "a DOWNLINK a pair and period"
    pipe.send((cost, periods))
    await until_stopped(pipe, profiler)


def core_floor(n: int, cpu: int | None) -> float:
    """µs of CPU per pair and period of RSP's own work for N pairs (`_core_floor`), on `cpu`."""
    child = start_child("floor", _core_floor, cpu)
    try:
        child.pipe.send(n)
        cost, _ = answer(child, "its floor")
    finally:
        child.stop()
    return float(cost) * 1e6


# -- the measurer ------------------------------------------------------------------------------


class Stream:
    """One direction of one pair, as its receiver got it: packets of `kind` and their intervals
    (jitter, ns, appended to a list shared by the streams of a direction), sequence gaps."""

    __slots__ = ("at", "jitter", "kind", "lost", "packets", "sequence")

    def __init__(self, kind: int, jitter: list[int]) -> None:
        self.kind = kind
        self.jitter = jitter
        self.sequence: int | None = None
        self.at: int | None = None
        self.packets = self.lost = 0

    def see(self, kind: int, sequence: int, at: int) -> None:
        previous, self.sequence = self.sequence, sequence
        gap = 1 if previous is None else (sequence - previous) & 0xFFFF
        if 1 < gap < 0x8000:
            self.lost += gap - 1
        if kind != self.kind:
            self.at = None
            return
        self.packets += 1
        if gap == 1 and self.at is not None:  # an interval between consecutive packets only
            self.jitter.append(abs(at - self.at - PERIOD_NS))
        self.at = at


@dataclass
class Stamps:
    """A row's packets in the window by one clock: the kernel's or the measured process's."""

    downlink: list[int]  # jitter, ns, sorted
    uplink: list[int]
    packets: int
    lost: int
    silent: int
    jitter: list[int] = field(init=False)

    def __post_init__(self) -> None:
        self.downlink.sort()
        self.uplink.sort()
        self.jitter = sorted(self.downlink + self.uplink)

    @classmethod
    def of(cls, streams: list[tuple[Stream, Stream]], down: list[int], up: list[int]) -> Stamps:
        """From each pair's (DOWNLINKs at the robot, UPLINKs at the local side)."""
        return cls(
            down,
            up,
            sum(a.packets + b.packets for a, b in streams),
            sum(a.lost + b.lost for a, b in streams),
            sum(1 for a, b in streams if not a.packets or not b.packets),
        )

    @classmethod
    def received(cls, seen: list[tuple[tuple[Any, Any], tuple[Any, Any]]]) -> Stamps:
        """From what the measured process received in the window (`Arrivals.between`)."""
        down: list[int] = []
        up: list[int] = []
        streams = []
        for at_robot, at_local in seen:
            pair = (Stream(DOWNLINK, down), Stream(UPLINK, up))
            for stream, (times, marks) in zip(pair, (at_robot, at_local), strict=True):
                for at, mark in zip(times, marks, strict=True):
                    stream.see(mark >> 16, mark & 0xFFFF, int(at * 1e9))
            streams.append(pair)
        return cls.of(streams, down, up)


class Sniffer:
    """Every UDP packet of the loopback interface as it enters a socket buffer, with the
    kernel's stamp; those of the watched pairs in the window go to their streams."""

    def __init__(self) -> None:
        sock = socket.socket(socket.AF_PACKET, socket.SOCK_DGRAM, socket.htons(ETH_P_IP))
        try:
            sock.bind(("lo", ETH_P_IP))
            sock.setsockopt(SOL_PACKET, PACKET_IGNORE_OUTGOING, 1)  # each packet once
            try:
                sock.setsockopt(socket.SOL_SOCKET, SO_RCVBUFFORCE, SNIFF_BUFFER)
            except OSError:
                sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, SNIFF_BUFFER)
            sock.setsockopt(socket.SOL_SOCKET, SO_TIMESTAMPNS, 1)
            code = b"".join(struct.pack("HBBI", *op) for op in UDP_ONLY)
            program = ctypes.create_string_buffer(code)
            fprog = struct.pack("HL", len(UDP_ONLY), ctypes.addressof(program))
            sock.setsockopt(socket.SOL_SOCKET, SO_ATTACH_FILTER, fprog)
            sock.setblocking(False)
        except BaseException:
            sock.close()
            raise
        self.sock = sock
        self.space = socket.CMSG_SPACE(16)
        self.window = (0, -1)
        self.streams: dict[bytes, Stream] = {}
        self.pairs: list[tuple[Stream, Stream]] = []
        self.down: list[int] = []
        self.up: list[int] = []

    @staticmethod
    def available() -> bool:
        try:
            Sniffer().close()
        except (OSError, AttributeError):  # not permitted (CAP_NET_RAW); not Linux
            return False
        return True

    def watch(self, pairs: Pairs) -> None:
        for robot, local in pairs:
            down, up = Stream(DOWNLINK, self.down), Stream(UPLINK, self.up)
            self.streams[struct.pack(">HH", local, robot)] = down
            self.streams[struct.pack(">HH", robot, local)] = up
            self.pairs.append((down, up))

    def start(self, start_ns: int, end_ns: int) -> None:
        """From now on, the packets stamped in [start, end); the socket's drop count reset."""
        self.drain()
        self.drops()
        self.window = (start_ns, end_ns)

    def drops(self) -> int:
        """Packets the socket dropped (its buffer full) since last asked."""
        _, dropped = struct.unpack("II", self.sock.getsockopt(SOL_PACKET, PACKET_STATISTICS, 8))
        return int(dropped)

    def drain(self) -> None:
        recvmsg, space, streams = self.sock.recvmsg, self.space, self.streams
        start, end = self.window
        while True:
            try:
                data, ancillary, _, _ = recvmsg(SNAP, space)
            except BlockingIOError:
                return
            ip = (data[0] & 0x0F) * 4
            if len(data) < ip + 15 or not ancillary:
                continue
            stream = streams.get(data[ip : ip + 4])
            if stream is None:
                continue
            at = stamp_ns(ancillary[0][2])
            if start <= at < end:
                rsp = ip + 8
                stream.see(data[rsp + 4], data[rsp + 5] << 8 | data[rsp + 6], at)

    def stamps(self) -> Stamps:
        return Stamps.of(self.pairs, self.down, self.up)

    def close(self) -> None:
        self.sock.close()


@dataclass
class Row:
    side: str  # "asyncio" or "batch" (RSP on that adapter), or "anchor"
    n: int
    seconds: float
    #: By the measured process's receipt stamps; by the kernel's (None: not measured).
    seen: Stamps
    kernel: Stamps | None
    usage: Usage
    #: Packets the measurer's packet socket dropped in the window (its figures miss them).
    sniffer_drops: int = 0
    tries: int = 1

    @property
    def stamps(self) -> Stamps:
        """The stamps the row is judged by: the kernel's where taken."""
        return self.kernel if self.kernel is not None else self.seen

    @property
    def lost(self) -> int:
        return self.seen.lost

    @property
    def silent(self) -> int:
        return self.seen.silent

    @property
    def rate(self) -> float:
        return self.stamps.packets / (2 * self.n * self.seconds / PERIOD)

    @property
    def cost(self) -> float:
        """CPU seconds of the measured process per pair and period served: per DOWNLINK and
        UPLINK sent (a saturated process serves fewer periods than N per T)."""
        packets = self.stamps.packets
        return self.usage.sender * self.seconds / (packets / 2) if packets else 0.0

    def percentile(self, p: float) -> float:
        return percentile(self.stamps.jitter, p)

    @property
    def passed(self) -> bool:
        return (
            self.percentile(99) <= MAX_JITTER_MS
            and self.lost == 0
            and self.silent == 0
            and self.rate >= MIN_RATE
        )

    def as_json(self, anchor: Row | None = None) -> dict[str, Any]:
        def view(stamps: Stamps | None) -> dict[str, Any] | None:
            if stamps is None:
                return None

            def p(jitter: list[int], at: float) -> float | None:
                found = percentile(jitter, at)
                return found if math.isfinite(found) else None

            return {
                "p50_ms": p(stamps.jitter, 50),
                "p99_ms": p(stamps.jitter, 99),
                "max_ms": p(stamps.jitter, 100),
                "downlink_p99_ms": p(stamps.downlink, 99),
                "uplink_p99_ms": p(stamps.uplink, 99),
                "intervals": len(stamps.jitter),
                "packets": stamps.packets,
            }

        usage = self.usage
        return {
            "n": self.n,
            "side": self.side,
            "tries": self.tries,
            "seconds": self.seconds,
            "packets_per_s": self.stamps.packets / self.seconds,
            "rate": self.rate,
            "kernel": view(self.kernel),
            "seen": view(self.seen),
            "lost": self.lost,
            "silent": self.silent,
            "sniffer_drops": self.sniffer_drops,
            "cpu": usage.sender,
            "us_per_pair_period": self.cost * 1e6,
            "others_cpu": usage.other,
            "steal": usage.steal,
            "measurer_cpu": usage.generator,
            "verdict": verdict(self, anchor, NOISY),
        }


def measure(
    child: Child, sniffer: Sniffer | None, cpu: int | None, warm_up: float, seconds: float
) -> tuple[tuple[float, float], Usage, int]:
    """Warm-up, then the window: (its start and end by the loop's clock), CPU use, sniffer drops."""
    warm_end = time.monotonic() + warm_up
    while time.monotonic() < warm_end:
        time.sleep(POLL_EVERY)
        if sniffer is not None:
            sniffer.drain()
    start_ns, start = time.time_ns(), time.monotonic()
    if sniffer is not None:
        sniffer.start(start_ns, start_ns + int(seconds * 1e9))
    probe = UsageProbe(child.pid, cpu)
    end = start + seconds
    while time.monotonic() < end:
        time.sleep(POLL_EVERY)  # not waiting in epoll: no wake-up for the senders to pay
        if sniffer is not None:
            sniffer.drain()
    usage = probe.usage()
    drops = 0
    if sniffer is not None:
        time.sleep(POLL_EVERY)
        sniffer.drain()
        drops = sniffer.drops()
    return (start, end), usage, drops


def answer(child: Child, what: str) -> Any:
    """The child's next message (SETUP_TIMEOUT at most)."""
    try:
        if child.pipe.poll(SETUP_TIMEOUT):
            return child.pipe.recv()
    except (EOFError, OSError):
        raise RuntimeError(f"the {child.kind} process ended before it sent {what}") from None
    raise RuntimeError(f"the {child.kind} process sent no {what}")


def run(
    side: str, n: int, cpu: int | None, args: argparse.Namespace, profile: bool = False
) -> tuple[Row, str | None]:
    """One row: N pairs of RSP on an adapter ("asyncio", "batch") or of the anchor ("anchor")
    in one process on `cpu`."""
    main = MAINS.get(side, _anchor_pairs)
    child = start_child(side, main, cpu, "rcmlconf|asyncio" if profile else None)
    sniffer: Sniffer | None = None
    report = None
    try:
        child.pipe.send(n)
        pairs: Pairs = answer(child, "its pairs' ports")
        if args.stamps == "kernel":
            sniffer = Sniffer()
            sniffer.watch(pairs)
        window, usage, drops = measure(child, sniffer, cpu, args.warm_up, args.seconds)
        child.pipe.send(window)  # the child stops, and sends what it received in the window
        seen = Stamps.received(answer(child, "its stamps"))
        kernel = sniffer.stamps() if sniffer is not None else None
        row = Row(side, n, args.seconds, seen, kernel, usage, drops)
    finally:
        report = child.stop()
        if sniffer is not None:
            sniffer.close()
    return row, report


def row_of(side: str, n: int, cpu: int | None, args: argparse.Namespace) -> Row:
    return run(side, n, cpu, args)[0]


def print_row(row: Row, anchor: Row | None = None, out: TextIO = sys.stdout) -> None:
    usage = row.usage
    seen = row.seen.jitter
    warn = f"  (the measurer missed {row.sniffer_drops} packets)" if row.sniffer_drops else ""
    print(
        f"{row.n:>5} {row.side:<7} {row.tries:>5} {row.stamps.packets / row.seconds:>9,.0f}"
        f" {row.rate:>6.1%} {row.percentile(50):>6.2f} {row.percentile(99):>6.2f}"
        f" {row.percentile(100):>6.2f} {percentile(seen, 99):>6.2f} {percentile(seen, 100):>7.2f}"
        f" {row.lost:>5} {row.silent:>6} {usage.sender:>5.0%} {row.cost * 1e6:>7.1f}"
        f" {usage.other:>6.0%} {usage.steal:>6.1%} {usage.generator:>5.0%}"
        f"  {verdict(row, anchor, NOISY)}{warn}",
        file=out,
        flush=True,
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--max-n", type=int, default=1000)
    parser.add_argument("--seconds", type=float, default=8.0, help="measured, per row")
    parser.add_argument("--warm-up", type=float, default=2.0)
    parser.add_argument("--tries", type=int, default=3, help="runs of an N that fails, at most")
    parser.add_argument("--quick", action="store_true", help="N = 50 and 200, 2 s each, 1 try each")
    parser.add_argument("--keep-going", action="store_true", help="every N, past a failure")
    parser.add_argument(
        "--stamps",
        choices=("kernel", "process"),
        help="whose receive stamps judge a row (default: the kernel's where a packet socket"
        " may be opened, CAP_NET_RAW)",
    )
    parser.add_argument("--json", action="store_true", help="JSON on stdout, the table on stderr")
    parser.add_argument(
        "--adapter",
        choices=("batch", "asyncio", "both"),
        default="both",
        help="the RSP adapter(s) measured (both: the asyncio one as the before, the batch after)",
    )
    parser.add_argument("--profile", type=int, metavar="N", help="profile the RSP process at N")
    args = parser.parse_args()
    # A termination unwinds like Ctrl-C does, through the `finally`s that stop the children.
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))
    if args.quick:
        args.seconds, args.warm_up, args.tries = min(args.seconds, 2.0), min(args.warm_up, 1), 1
    note = ""
    if args.stamps is None:
        args.stamps = "kernel" if Sniffer.available() else "process"
        if args.stamps == "process":
            note = " (no packet socket here: CAP_NET_RAW)"
    out = sys.stderr if args.json else sys.stdout
    measured_cpu, measurer_cpu = split_cpus()
    where = (
        f"the pairs on CPU {measured_cpu}, the measurer on CPU {measurer_cpu}"
        if measured_cpu is not None
        else "one CPU: the pairs and the measurer share it"
    )
    adapters = ["asyncio", "batch"] if args.adapter == "both" else [args.adapter]
    if args.profile:
        row, report = run(adapters[-1], args.profile, measured_cpu, args, profile=True)
        print(f"N = {args.profile}: the RSP process under cProfile ({where})")
        print_row(row)
        print(report or "(no profile came back)")
        return
    clock = "the kernel's receive stamps" if args.stamps == "kernel" else "receipt in the process"
    lines = [
        f"N RSP pairs (CUBO) at T = 20 ms in one process; {where}; load average {load_average()}",
        f"jitter = |interval between a session's DOWNLINKs at the robot (UPLINKs at the local side)"
        f" - 20 ms| by {clock}{note}; seen: by receipt in the process;"
        f" over {args.seconds:g} s after {args.warm_up:g} s of warm-up",
        f"pass: p99 <= {MAX_JITTER_MS:g} ms, nothing lost, no pair silent, rate >= 99%;"
        f" a row is the best of up to {args.tries} tries; noisy: RSP failed by jitter alone, the"
        f" anchor too, p99 <= {NOISY:g} x the anchor's",
        "RSP on the adapters: asyncio (a transport and a timer an endpoint), batch (one reader"
        " and one clock for all, rcmlconf.reference.rsp.batch)",
        "anchor: N pairs of bare asyncio UDP sockets sending RSP's packets (loop.call_at);"
        " CPU: the measured process, others and steal on its CPU, the measurer;"
        " ratios: µs of CPU per pair and period, and CPU, of each adapter to the anchor's",
        f"{'N':>5} {'side':<7} {'tries':>5} {'packets/s':>9} {'rate':>6} {'p50':>6} {'p99':>6}"
        f" {'max':>6} {'seen99':>6} {'seenmax':>7} {'lost':>5} {'silent':>6} {'CPU':>5}"
        f" {'µs/pair':>7} {'others':>6} {'steal':>6} {'mCPU':>5}",
    ]
    for line in lines:
        print(line, file=out, flush=True)
    rows: list[dict[str, Any]] = []
    best = dict.fromkeys(adapters, 0)
    held = dict.fromkeys(adapters, 0)
    last: dict[str, Row] = {}
    running = list(adapters)  # an adapter that FAILed is not run at a larger N
    floors: dict[int, float] = {}
    try:
        for n in steps(args.max_n, args.quick, STEPS):
            if not running:
                break
            anchor = best_of(functools.partial(row_of, "anchor", n, measured_cpu, args), args.tries)
            ratios = []
            done = [("anchor", anchor)]
            for adapter in list(running):
                row = best_of(functools.partial(row_of, adapter, n, measured_cpu, args), args.tries)
                last[adapter] = row
                done.append((adapter, row))
                print_row(row, anchor, out)
                rows.append(row.as_json(anchor))
                outcome = verdict(row, anchor, NOISY)
                best[adapter] = n if outcome == "pass" else best[adapter]
                held[adapter] = n if outcome != "FAIL" else held[adapter]
                if outcome == "FAIL" and not (args.keep_going or args.quick):
                    running.remove(adapter)
                if anchor.cost and anchor.usage.sender:
                    ratios.append(
                        f"{adapter}/anchor µs/pair {row.cost / anchor.cost:.2f},"
                        f" CPU {row.usage.sender / anchor.usage.sender:.2f}"
                    )
            print_row(anchor, None, out)
            rows.append(anchor.as_json())
            floor = floors[n] = core_floor(n, measured_cpu)
            print(
                f"{n:>5} floor   RSP's own work in memory, no socket: {floor:.1f} µs of CPU a pair"
                f" and period, {floor * n / (PERIOD * 1e6):.0%} of a core",
                file=out,
            )
            ratios += [f"{side}/floor µs/pair {row.cost * 1e6 / floor:.2f}" for side, row in done]
            print(f"{'':>5} ratios {'; '.join(ratios)}", file=out, flush=True)
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
    summary = []
    full_at: dict[str, int | None] = dict.fromkeys(adapters)
    for adapter in adapters:
        goal = "met" if best[adapter] >= GOAL_N else "NOT met"
        summary.append(
            f"{adapter}: largest N that passed: {best[adapter] or 'none'}"
            f" (goal N >= {GOAL_N}: {goal})"
        )
        if held[adapter] > best[adapter]:
            summary.append(f"  largest N passed or noisy (the anchor too failed): {held[adapter]}")
        final = last.get(adapter)
        if final is not None and final.cost and final.usage.sender >= 0.5:  # fixed costs thin
            full_at[adapter] = round(PERIOD / final.cost)
            summary.append(
                f"  at N = {final.n} the pairs took {final.cost * 1e6:.0f} µs of CPU per pair and"
                f" period: one core is full at N = {full_at[adapter]}, whatever the jitter"
            )
    for line in summary:
        print(line, file=out, flush=True)
    if args.json:
        document = {
            "bench": "rsp_pairs_scale",
            "period_ms": PERIOD * 1000,
            "goal_n": GOAL_N,
            "max_jitter_ms": MAX_JITTER_MS,
            "stamps": args.stamps,
            "where": where,
            "load_average": load_average(),
            "seconds": args.seconds,
            "warm_up": args.warm_up,
            "adapters": adapters,
            "rows": rows,
            "largest_n_passed": best,
            "largest_n_passed_or_noisy": held,
            "goal_met": {adapter: n >= GOAL_N for adapter, n in best.items()},
            "core_full_at_n": full_at,
            "floor_us_per_pair_period": floors,
        }
        json.dump(document, sys.stdout, indent=2)
        print()


if __name__ == "__main__":
    main()
