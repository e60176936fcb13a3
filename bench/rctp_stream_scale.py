"""How many 16 ms read streams does the reference server hold on one core? (issue 5, "stream")

N sessions each play the camera robot's stream access /stream/control in mode `read`, at its
RCML interval of 16 ms (the paper's). The figure is the largest N the server holds with p99
send-interval jitter <= 2 ms, nothing lost; goal: N >= 500.

How: the server runs in its own process pinned to the first CPU (`os.sched_setaffinity`), a fresh
one for each N; this process, the load generator, is pinned to the last CPU. It opens N control
connections and sends each session's CONNECT and SETUP (`Transport: udp;client_port=P;mode=read`)
as raw RCTP messages, in batches, then the GOs spread over one interval (so that the beats are
spread as independent clients' would be). --per-port sessions share one UDP client port (each
session has its own tag). Every session sends a FLOW heartbeat every 5 s from its port, as the
reference client does (R-RCTP-49). The UDP sockets have 4 MB receive buffers and SO_TIMESTAMPNS:
every 2 ms the load generator drains the ready ones (epoll, without waiting in it: a receiver
blocked in epoll would make each sendto pay for waking it up) with recvmsg, and keeps each
packet's kernel arrival time (on loopback, stamped right after the sender's sendto), so the load
generator's own delays do not count.

After --warm-up, for --seconds: jitter (ms) is |interval between one session's consecutive DATA
packets - 16 ms|, over all sessions (p50, p99, max); `lost` is the gaps in each session's sequence
numbers (a saturated receiver shows up there, not as jitter); `silent`, sessions that sent
nothing; `rate`, DATA packets received over N / 16 ms (beats skipped by a sender that fell behind
lower it). CPU, from /proc over the window: the sender's (and its CPU time per packet, `µs/pkt`),
what other processes and the hypervisor (`steal`) took of its CPU, the load generator's. A row
that fails is run again, up to --tries runs, and the best is shown: the machine is shared, and
its noise only adds jitter. A server row that fails by jitter alone, where the anchor failed too
with a p99 not much lower (1.5 times), is `noisy`: the machine's doing as far as the run can
tell. N goes up the list until a server row FAILs (--keep-going: every N); the last line says at
which N the server's CPU time per packet (at the last N, if it kept the server half busy) fills
one core, jitter aside.

Anchor, in the same run and for each N: a minimal asyncio UDP sender in the server's place (one
process on the same CPU, N streams of 36-byte packets like the server's, each rescheduled with
`loop.call_at` every 16 ms on the beat): how much of the jitter is the machine and asyncio.

    python bench/rctp_stream_scale.py [--max-n 1000] [--seconds 8] [--warm-up 2] [--tries 3]
    python bench/rctp_stream_scale.py --quick            # N = 50 and 200, 2 s each, one run
    python bench/rctp_stream_scale.py --profile 400      # the server under cProfile, N = 400
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import cProfile
import random
import re
import selectors
import signal
import socket
import struct
import sys
import time
from collections import deque
from dataclasses import dataclass
from multiprocessing.connection import Connection

from children import Child, serve_camera, start_child, until_stopped
from scale import (
    SO_TIMESTAMPNS,
    TIMESPEC,
    Usage,
    UsageProbe,
    load_average,
    percentile,
    split_cpus,
    steps,
)
from scale import best_of as _best_of
from scale import verdict as _verdict

STREAM = "/stream/control"
INTERVAL = 0.016
INTERVAL_NS = 16_000_000
GOAL_N = 500
MAX_JITTER_MS = 2.0
#: A server row failed by jitter alone is `noisy` where the anchor failed too, with a p99 at
#: most this many times the anchor's.
NOISY = 1.5
STEPS = (50, 100, 200, 300, 400, 500, 600, 800, 1000, 1200, 1500, 2000)
HEARTBEAT_EVERY = 5.0
#: Sessions set up together: a batch's CONNECTs go out at once, then its SETUPs.
BATCH = 50
RECEIVE_BUFFER = 4 << 20
#: The load generator sleeps this long between draining its sockets: a receiver blocked in
#: epoll would make every sendto of the sender wake it (an inter-processor interrupt, costly in a
#: VM, paid in the sender's CPU time), which a server's real, remote clients do not cost it.
POLL_EVERY = 0.002
#: The anchor's packet: version 2, one payload, sequence, tag, NTP time; DATA, stream 1, 16 bytes.
HEADER = struct.Struct(">BBHIQBBH")
NTP_EPOCH = 2_208_988_800


# -- the processes in the server's place ------------------------------------------------------


class _Ignore(asyncio.DatagramProtocol):
    """The anchor's socket: heartbeats arrive and are dropped."""


async def _anchor(pipe: Connection, profiler: cProfile.Profile | None) -> None:
    """N streams of DATA packets, each sent every 16 ms on its beat with loop.call_at."""
    loop = asyncio.get_running_loop()
    transport, _ = await loop.create_datagram_endpoint(_Ignore, local_addr=("127.0.0.1", 0))
    pipe.send((0, transport.get_extra_info("sockname")[1], ""))
    streams: list[tuple[int, int]] = pipe.recv()  # (tag, client port) of each stream
    body = bytes(16)
    offset = time.time() - loop.time() + NTP_EPOCH
    sequence = [random.randrange(1 << 16) for _ in streams]
    sending = True

    def send(index: int, due: float) -> None:
        if not sending:
            return
        now = loop.time()
        tag, port = streams[index]
        stamp = int((now + offset) * (1 << 32)) & 0xFFFF_FFFF_FFFF_FFFF  # NTP eras wrap
        packet = HEADER.pack(2, 1, sequence[index], tag, stamp, 1, 1, len(body)) + body
        transport.sendto(packet, ("127.0.0.1", port))
        sequence[index] = (sequence[index] + 1) & 0xFFFF
        after = due + INTERVAL
        after = after if after > now else now + INTERVAL
        loop.call_at(after, send, index, after)

    start = loop.time()
    for index in range(len(streams)):
        first = start + random.uniform(0, INTERVAL)
        loop.call_at(first, send, index, first)
    try:
        await until_stopped(pipe)
    finally:
        sending = False
        transport.close()


# -- the load generator -----------------------------------------------------------------------


def receivers(count: int) -> list[socket.socket]:
    sockets = []
    try:
        for _ in range(count):
            sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            sockets.append(sock)
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, RECEIVE_BUFFER)
            sock.setsockopt(socket.SOL_SOCKET, SO_TIMESTAMPNS, 1)
            sock.bind(("127.0.0.1", 0))
            sock.setblocking(False)
    except BaseException:
        for sock in sockets:
            sock.close()
        raise
    return sockets


def drain(sockets: list[socket.socket]) -> None:
    for sock in sockets:
        with contextlib.suppress(BlockingIOError):
            while True:
                sock.recv(2048)


def _response(sock: socket.socket, buffer: bytearray) -> bytes:
    while (end := buffer.find(b"\r\n\r\n")) < 0:
        chunk = sock.recv(65536)
        if not chunk:
            raise ConnectionError("the server closed a control connection")
        buffer += chunk
    length = re.search(rb"\r\nContent-Length: *(\d+)", bytes(buffer[:end]), re.IGNORECASE)
    total = end + 4 + (int(length.group(1)) if length else 0)
    while len(buffer) < total:
        chunk = sock.recv(65536)
        if not chunk:
            raise ConnectionError("the server closed a control connection")
        buffer += chunk
    response = bytes(buffer[:total])
    del buffer[:total]
    if response[9:12] != b"200":
        raise RuntimeError(f"the server refused: {response[:300]!r}")
    return response


def exchange(sockets: list[socket.socket], requests: list[str]) -> list[bytes]:
    """One request on each connection, all sent before any answer is read."""
    for sock, request in zip(sockets, requests, strict=True):
        sock.sendall(request.encode())
    return [_response(sock, bytearray()) for sock in sockets]


def _field(pattern: bytes, response: bytes) -> str:
    found = re.search(pattern, response)
    if found is None:
        raise RuntimeError(f"no {pattern!r} in {response[:300]!r}")
    return found.group(1).decode()


def open_sessions(
    server: Child, ports: list[int], per_port: int, udp: list[socket.socket]
) -> tuple[list[socket.socket], list[int]]:
    """N sessions playing the stream: their control connections and their tags.

    CONNECT and SETUP go in batches; then the GOs are spread over one interval, so that the
    streams' beats are spread as independent clients' would be (and as the anchor's are)."""
    n = len(ports) * per_port
    controls: list[socket.socket] = []
    tags: list[int] = []
    ids: list[str] = []
    try:
        for first in range(0, n, BATCH):
            count = min(BATCH, n - first)
            batch = [
                socket.create_connection(("127.0.0.1", server.ready[0]), 30) for _ in range(count)
            ]
            controls.extend(batch)
            for sock in batch:
                sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            connect = f"CONNECT {server.ready[2]} RCTP/2.0\r\nCSeq: 1\r\nUser-Agent: bench\r\n\r\n"
            answers = exchange(batch, [connect] * count)
            batch_ids = [_field(rb"\r\nSession: ([^;\r]+)", answer) for answer in answers]
            setups = [
                f"SETUP {STREAM} RCTP/2.0\r\nCSeq: 2\r\nSession: {session}\r\n"
                f"Transport: udp;client_port={ports[(first + i) // per_port]};mode=read\r\n\r\n"
                for i, session in enumerate(batch_ids)
            ]
            tags.extend(int(_field(rb";tag=([0-9a-f]+)", r), 16) for r in exchange(batch, setups))
            ids.extend(batch_ids)
        start = time.monotonic()
        for i, (sock, session) in enumerate(zip(controls, ids, strict=True)):
            ahead = start + i * INTERVAL / n - time.monotonic()
            if ahead > 0:
                time.sleep(ahead)
            sock.sendall(f"GO {STREAM} RCTP/2.0\r\nCSeq: 3\r\nSession: {session}\r\n\r\n".encode())
        for first in range(0, n, BATCH):
            for sock in controls[first : first + BATCH]:
                _response(sock, bytearray())
            drain(udp)
    except BaseException:
        for sock in controls:
            sock.close()
        raise
    return controls, tags


class Heartbeats:
    """Every session's FLOW heartbeat request every 5 s, from its client port (R-RCTP-49)."""

    def __init__(self, tags: list[int], sockets: list[socket.socket], per_port: int, to: int):
        from rcmlconf.rctp.datastream.clock import ntp_from_unix
        from rcmlconf.rctp.datastream.flow import HeartbeatRequest
        from rcmlconf.rctp.datastream.packets import FlowPayload, Packet, push_packet

        def packet(sequence: int, tag: int, request_id: int) -> bytes:
            now = ntp_from_unix(time.time())
            payload = FlowPayload(0, HeartbeatRequest(request_id, now))
            return push_packet(Packet(sequence, tag, now, (payload,)))

        self.packet = packet
        self.to = ("127.0.0.1", to)
        start = time.monotonic()
        self.due: deque[tuple[float, int]] = deque(
            (start + HEARTBEAT_EVERY * i / max(1, len(tags)), i) for i in range(len(tags))
        )
        self.tags = tags
        self.sockets = [sockets[i // per_port] for i in range(len(tags))]
        self.sequence = [random.randrange(1 << 16) for _ in tags]
        self.sent = 0

    def send_due(self, now: float) -> None:
        due = self.due
        while due and due[0][0] <= now:
            when, i = due.popleft()
            packet = self.packet(self.sequence[i], self.tags[i], self.sent & 0xFFFF)
            with contextlib.suppress(BlockingIOError):
                self.sockets[i].sendto(packet, self.to)
            self.sequence[i] = (self.sequence[i] + 1) & 0xFFFF
            self.sent += 1
            due.append((when + HEARTBEAT_EVERY, i))


@dataclass
class Row:
    n: int
    seconds: float
    data_packets: int
    jitter: list[int]  # nanoseconds, sorted
    lost: int
    silent: int
    usage: Usage
    tries: int = 1

    @property
    def cost(self) -> float:
        """The sender's CPU seconds per DATA packet."""
        return self.usage.sender * self.seconds / self.data_packets if self.data_packets else 0.0

    @property
    def rate(self) -> float:
        return self.data_packets / self.seconds / (self.n / INTERVAL)

    def percentile(self, p: float) -> float:
        """Jitter in ms at percentile p (nearest rank)."""
        return percentile(self.jitter, p)

    @property
    def passed(self) -> bool:
        return (
            self.percentile(99) <= MAX_JITTER_MS
            and self.lost == 0
            and self.silent == 0
            and self.rate >= 0.99
        )


def receive(
    sockets: list[socket.socket],
    tags: list[int],
    heartbeats: Heartbeats,
    sender: tuple[int | None, int | None],
    warm_up: float,
    seconds: float,
) -> Row:
    """Drain the sockets for warm_up + seconds; measure the last `seconds` by kernel stamps.
    `sender` is the process in the server's place and its CPU."""
    selector = selectors.DefaultSelector()
    for sock in sockets:
        selector.register(sock, selectors.EVENT_READ)
    heads: list[bytes] = []
    stamps: list[bytes] = []
    space = socket.CMSG_SPACE(TIMESPEC.size)
    now = time.monotonic()
    warm_end, end = now + warm_up, now + warm_up + seconds
    window: tuple[int, int] | None = None
    probe: UsageProbe | None = None
    try:
        while (now := time.monotonic()) < end:
            if window is None and now >= warm_end:
                heads.clear()
                stamps.clear()
                start_ns = time.time_ns()
                window = (start_ns, start_ns + int(seconds * 1e9))
                probe = UsageProbe(*sender)
            heartbeats.send_due(now)
            time.sleep(POLL_EVERY)  # not waiting in epoll: no wake-up for the sender to pay
            for key, _ in selector.select(0):
                recvmsg = key.fileobj.recvmsg  # type: ignore[union-attr]
                while True:
                    try:
                        data, ancillary, _, _ = recvmsg(17, space)
                    except BlockingIOError:
                        break
                    heads.append(data)
                    stamps.append(ancillary[0][2])
    finally:
        selector.close()
    assert window is not None
    assert probe is not None
    usage = probe.usage()
    return summarise(len(tags), seconds, tags, heads, stamps, window, usage)


def summarise(
    n: int,
    seconds: float,
    tags: list[int],
    heads: list[bytes],
    stamps: list[bytes],
    window: tuple[int, int],
    usage: Usage,
) -> Row:
    known = {tag.to_bytes(4, "big") for tag in tags}
    last_sequence: dict[bytes, int] = {}
    last_data: dict[bytes, int] = {}
    jitter: list[int] = []
    lost = data_packets = 0
    start, stop = window
    for head, stamp in zip(heads, stamps, strict=True):
        seconds_part, nanoseconds = TIMESPEC.unpack(stamp)
        at = seconds_part * 1_000_000_000 + nanoseconds
        tag = head[4:8]
        if not start <= at < stop or tag not in known:
            continue
        sequence = head[2] << 8 | head[3]
        before = last_sequence.get(tag)
        if before is not None:
            gap = (sequence - before) & 0xFFFF
            lost += gap - 1 if 0 < gap < 0x8000 else 0
        last_sequence[tag] = sequence
        if len(head) > 16 and head[16] == 1:  # a DATA payload first: a beat
            data_packets += 1
            previous = last_data.get(tag)
            if previous is not None:
                jitter.append(abs(at - previous - INTERVAL_NS))
            last_data[tag] = at
    jitter.sort()
    silent = n - len(last_data)
    return Row(n, seconds, data_packets, jitter, lost, silent, usage)


def run(
    kind: str, n: int, cpu: int | None, args: argparse.Namespace, profile: bool = False
) -> tuple[Row, str | None]:
    """One row: N streams from the reference server ("rctp") or the anchor ("anchor")."""
    per_port = max(1, min(args.per_port, n))
    ports_needed = -(-n // per_port)
    udp = receivers(ports_needed)
    controls: list[socket.socket] = []
    child: Child | None = None
    report = None
    try:
        ports = [sock.getsockname()[1] for sock in udp]
        main = serve_camera if kind == "rctp" else _anchor
        child = start_child(kind, main, cpu, "rcmlconf|asyncio" if profile else None)
        if kind == "rctp":
            controls, tags = open_sessions(child, ports, per_port, udp)
            tags = tags[:n]
        else:
            tags = random.sample(range(1, 1 << 32), n)
            child.pipe.send([(tag, ports[i // per_port]) for i, tag in enumerate(tags)])
        heartbeats = Heartbeats(tags, udp, per_port, child.ready[1])
        sender = (child.pid, cpu)
        row = receive(udp, tags, heartbeats, sender, args.warm_up, args.seconds)
    finally:
        for sock in controls:  # the sessions end: the server's shutdown waits for no BYE
            sock.close()
        if child is not None:
            time.sleep(0.2 if controls else 0)
            report = child.stop()
        for sock in udp:
            sock.close()
    return row, report


def verdict(row: Row, anchor: Row | None = None) -> str:
    """pass; FAIL; or `noisy`: failed by jitter alone where the anchor failed too, with a p99
    at most NOISY times the anchor's (the machine's doing, as far as this run can tell)."""
    return _verdict(row, anchor, NOISY)


def print_row(label: str, row: Row, anchor: Row | None = None) -> None:
    usage = row.usage
    print(
        f"{row.n:>5} {label:<6} {row.tries:>5} {row.data_packets / row.seconds:>9,.0f}"
        f" {row.rate:>6.1%} {row.percentile(50):>6.2f} {row.percentile(99):>6.2f}"
        f" {row.percentile(100):>6.2f} {row.lost:>5} {row.silent:>6} {usage.sender:>7.0%}"
        f" {row.cost * 1e6:>6.1f} {usage.other:>6.0%} {usage.steal:>6.1%}"
        f" {usage.generator:>6.0%}  {verdict(row, anchor)}",
        flush=True,
    )


def best_of(kind: str, n: int, cpu: int | None, args: argparse.Namespace) -> Row:
    """Up to --tries rows until one passes; the best (the machine's noise only adds jitter)."""
    return _best_of(lambda: run(kind, n, cpu, args)[0], args.tries)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--max-n", type=int, default=1000)
    parser.add_argument("--seconds", type=float, default=8.0, help="measured, per row")
    parser.add_argument("--warm-up", type=float, default=2.0)
    parser.add_argument("--per-port", type=int, default=10, help="sessions per UDP client port")
    parser.add_argument("--tries", type=int, default=3, help="runs of an N that fails, at most")
    parser.add_argument("--quick", action="store_true", help="N = 50 and 200, 2 s each, 1 try")
    parser.add_argument("--keep-going", action="store_true", help="every N, past a failure")
    parser.add_argument("--profile", type=int, metavar="N", help="profile the server at N")
    args = parser.parse_args()
    # A termination unwinds like Ctrl-C does, through the `finally`s that stop the children.
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))
    if args.quick:
        args.seconds, args.warm_up, args.tries = min(args.seconds, 2.0), min(args.warm_up, 1), 1
    server_cpu, generator_cpu = split_cpus()
    where = (
        f"server on CPU {server_cpu}, load generator on CPU {generator_cpu}"
        if server_cpu is not None
        else "one CPU: the server and the load generator share it"
    )
    if args.profile:
        row, report = run("rctp", args.profile, server_cpu, args, profile=True)
        print(f"N = {args.profile}: the reference server under cProfile ({where})")
        print_row("server", row)
        print(report or "(no profile came back)")
        return
    load = load_average()
    print(f"N sessions, each a read stream of {STREAM} every 16 ms; {where}; load average {load}")
    print(
        f"jitter = |interval between a session's DATA packets - 16 ms| by kernel receive stamps,"
        f" over {args.seconds:g} s after {args.warm_up:g} s of warm-up"
    )
    print(
        f"pass: p99 <= {MAX_JITTER_MS:g} ms, nothing lost, no session silent, rate >= 99%;"
        f" a row is the best of up to {args.tries} tries; noisy: the server failed by jitter"
        f" alone, the anchor too, p99 <= {NOISY:g} x the anchor's"
    )
    print(
        "anchor: a minimal asyncio UDP sender (loop.call_at per stream) in the server's place;"
        " CPU: sender, others and steal on its CPU, load generator"
    )
    print(
        f"{'N':>5} {'sender':<6} {'tries':>5} {'packets/s':>9} {'rate':>6} {'p50':>6} {'p99':>6}"
        f" {'max':>6} {'lost':>5} {'silent':>6} {'sendCPU':>7} {'µs/pkt':>6} {'others':>6}"
        f" {'steal':>6} {'genCPU':>6}"
    )
    best = held = 0
    last: Row | None = None
    try:
        for n in steps(args.max_n, args.quick, STEPS):
            last = row = best_of("rctp", n, server_cpu, args)
            anchor = best_of("anchor", n, server_cpu, args)
            print_row("server", row, anchor)
            print_row("anchor", anchor)
            outcome = verdict(row, anchor)
            best = n if outcome == "pass" else best
            held = n if outcome != "FAIL" else held
            if outcome == "FAIL" and not args.keep_going:
                break
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
    goal = "met" if best >= GOAL_N else "NOT met"
    print(f"largest N that passed: {best or 'none'} (goal N >= {GOAL_N}: {goal})")
    if held > best:
        print(f"largest N passed or noisy (the anchor failed there too): {held}")
    if last is not None and last.cost and last.usage.sender >= 0.5:  # fixed costs spread thin
        print(
            f"at N = {last.n} the server spent {last.cost * 1e6:.1f} µs of CPU per packet: one"
            f" core is full at N = {1 / (last.cost / INTERVAL):.0f}, whatever the jitter"
        )


if __name__ == "__main__":
    main()
