"""Does the RSP robot hold up under a flood of hostile datagrams? (issue 18)

`rcmlconf robot` runs as a process of its own on loopback (the vectors' every-kind model, T = 5
ms, a generic body whose monitors echo its effectors); a local system, the reference
`Simulacrum`, keeps a session with it from this process: `arm` written, `armActual` heard in
every UPLINK. First it writes an old value, keeping what it sends, then a new one, and the rows
begin: alone, then under a flood at each --rates datagrams a second, each for --seconds, from a
niced process of its own at another address (127.0.0.2): a third garbage, a third the session's
old DOWNLINKs with newer sequence numbers (its session ID spoofed), a third those DOWNLINKs
replayed as they were; the session's own socket replays them too, 200 a second (what an attacker
on the path could send from the local system's address).

Per row: the gap between consecutive UPLINKs at the local system (ms, p99 and max, by arrival in
this process's loop), UPLINKs lost (sequence gaps), `old`: an `armActual` other than the new value
(a replay or a spoofed packet taken), the session closed, lines on the robot's standard error, its
CPU and RSS, datagrams the kernel dropped at its port (a full buffer: hostile and legitimate
alike), and the flood actually sent. The anchor is the alone row of the same run: the machine is
shared, and noisy.

    python bench/hostile_rsp.py                    # 10 s a row, 10,000 and 50,000 a second
    python bench/hostile_rsp.py --seconds 3 --rates 10000
"""

from __future__ import annotations

import argparse
import asyncio
import multiprocessing
import os
import random
import socket
import sys
import tempfile
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from itertools import pairwise
from multiprocessing.connection import Connection
from pathlib import Path

from children import cpu_seconds
from hostile_load import Command, rss_mib, udp_drops
from scale import percentile

# The flood's spoofed packets are the test's (tests/reference/test_rsp_hostile.py): one recipe.
sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
from support.rsp_flood import spoofed

from rcmlconf.reference.rsp.simulacrum import Simulacrum
from rcmlconf.rsp.codec.header import TYPE_AT, PacketType
from rcmlconf.validate.validator import load_robot_model
from rcmlconf.values import Value

MODEL = Path(__file__).resolve().parent.parent / "vectors/xml/valid/rmodel-every-kind.rmodel"
OLD: dict[str, Value] = {"shoulder": 10, "elbow": 20, "grip": True}
NEW: dict[str, Value] = {"shoulder": -30, "elbow": 45, "grip": False}
ATTACKER = "127.0.0.2"
NICE = 10
#: The flood is sent in batches this often (s); the session's own replays, a batch this often.
TICK = 0.01
OWN_REPLAYS_EVERY = 0.05


class Robot(Command):
    """`rcmlconf robot` in a process of its own, its standard error in a file."""

    def __init__(self, folder: Path) -> None:
        command = [sys.executable, "-m", "rcmlconf", "robot", str(MODEL), "--port", "0"]
        super().__init__(folder, "robot", command)
        self.address = (str(self.found["host"]), int(self.found["port"]))


# -- the flood, in a process of its own --------------------------------------------------------


def flood(
    robot: tuple[str, int], old: list[bytes], rate: int, seconds: float, pipe: Connection
) -> None:
    """`rate` hostile datagrams a second for `seconds`; tells how many it sent, and its CPU."""
    os.nice(NICE)
    sent = 0
    cpu = time.process_time()
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind((ATTACKER, 0))
        sock.setblocking(False)
        start = time.monotonic()
        due = start
        while (now := time.monotonic()) < start + seconds:
            for _ in range(round(rate * TICK)):
                replay = old[sent % len(old)]
                kind = sent % 3
                data = (
                    random.randbytes(random.randrange(1, 200))
                    if kind == 0
                    else spoofed(replay, 1 + sent)
                    if kind == 1
                    else replay
                )
                try:
                    sock.sendto(data, robot)
                except OSError:  # a full send buffer: not sent, not counted
                    continue
                sent += 1
            due += TICK
            time.sleep(max(0.0, due - now))
    pipe.send((sent, time.process_time() - cpu))
    pipe.close()


# -- the rows ----------------------------------------------------------------------------------


@dataclass
class Row:
    name: str
    gap_p99: float
    gap_max: float
    lost: int
    old: int
    closed: bool
    log_lines: int
    robot_cpu: float
    rss_mib: float
    drops: int
    sent: int
    attacker_cpu: float


class Session:
    """The local system, what it hears, and its own replays of its old DOWNLINKs."""

    def __init__(self, local: Simulacrum, old: list[bytes], send: Callable[[bytes], None]) -> None:
        self.local = local
        self.old = old
        self.send = send
        self.heard: list[tuple[float, dict[str, Value]]] = []
        local.listen("armActual", self._heard)

    def _heard(self, values: Mapping[str, Value]) -> None:
        self.heard.append((time.monotonic(), dict(values)))

    async def replay(self, until: float) -> None:
        while time.monotonic() < until:
            for data in self.old[:10]:
                self.send(data)
            await asyncio.sleep(OWN_REPLAYS_EVERY)


async def open_session(robot: Robot) -> Session:
    model = load_robot_model(MODEL)
    local = Simulacrum(model, robot.address)
    await asyncio.wait_for(local.open(), 10)
    own = local._transport  # the local system's own socket, for the replays from its address
    assert own is not None
    sent: list[bytes] = []
    local.tap = sent.append
    local.set_active("armActual", True)
    local.write("arm", OLD)
    await _heard_value(local, OLD)
    local.tap = None
    old = [data for data in sent if data[TYPE_AT] == PacketType.DOWNLINK][-50:]
    local.write("arm", NEW)
    await _heard_value(local, NEW)
    return Session(local, old, own.sendto)


async def _heard_value(local: Simulacrum, value: Mapping[str, Value]) -> None:
    deadline = time.monotonic() + 10.0
    while local.latest("armActual") != value:
        if time.monotonic() > deadline:
            raise RuntimeError(f"the robot never echoed {value}")
        await asyncio.sleep(0.01)


async def row(name: str, robot: Robot, session: Session, rate: int, seconds: float) -> Row:
    log_before = robot.log().count("\n")
    lost_before = session.local.endpoint.received.lost
    drops_before = udp_drops(robot.address[1])
    cpu_before = cpu_seconds(robot.process.pid)
    start = time.monotonic()
    sent, attacker_cpu = 0, 0.0
    if rate:
        context = multiprocessing.get_context("spawn")
        ours, theirs = context.Pipe()
        process = context.Process(
            target=flood,
            args=(robot.address, session.old, rate, seconds, theirs),
            daemon=True,
        )
        process.start()
        theirs.close()
        await session.replay(start + seconds)
        loop = asyncio.get_running_loop()
        if await loop.run_in_executor(None, ours.poll, 30.0):
            sent, attacker_cpu = ours.recv()
        process.join(10)
        ours.close()
    else:
        await asyncio.sleep(seconds)
    end = time.monotonic()
    await asyncio.sleep(0.2)  # what was on its way
    inside = [(at, values) for at, values in session.heard if start <= at < end]
    gaps = sorted(round((b - a) * 1e9) for (a, _), (b, _) in pairwise(inside))
    return Row(
        name=name,
        gap_p99=percentile(gaps, 99),
        gap_max=gaps[-1] / 1e6 if gaps else float("inf"),
        lost=session.local.endpoint.received.lost - lost_before,
        old=sum(1 for _, values in inside if values != NEW),
        closed=session.local.closed is not None,
        log_lines=robot.log().count("\n") - log_before,
        robot_cpu=(cpu_seconds(robot.process.pid) - cpu_before) / (end - start),
        rss_mib=rss_mib(robot.process.pid),
        drops=udp_drops(robot.address[1]) - drops_before,
        sent=sent,
        attacker_cpu=attacker_cpu / (end - start),
    )


HEAD = (
    f"{'row':<16}{'gap p99':>8}{'max':>7}{'lost':>6}{'old':>5}{'closed':>7}{'log':>5}"
    f"{'CPU':>6}{'RSS':>6}{'drops':>8}{'sent':>9}{'atkCPU':>7}"
)


def line(found: Row) -> str:
    return (
        f"{found.name:<16}{found.gap_p99:>8.1f}{found.gap_max:>7.1f}{found.lost:>6}{found.old:>5}"
        f"{'yes' if found.closed else 'no':>7}{found.log_lines:>5}{found.robot_cpu:>6.0%}"
        f"{found.rss_mib:>6.0f}{found.drops:>8}{found.sent:>9,}{found.attacker_cpu:>7.0%}"
    )


async def run(robot: Robot, rates: list[int], seconds: float) -> list[Row]:
    session = await open_session(robot)
    rows = []
    try:
        for rate in (0, *rates):
            found = await row(
                f"flood {rate:,}/s" if rate else "alone", robot, session, rate, seconds
            )
            rows.append(found)
            print(line(found), flush=True)
    finally:
        await session.local.aclose()
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=10.0, help="each row (default 10)")
    parser.add_argument(
        "--rates", type=int, nargs="+", default=[10_000, 50_000], help="datagrams a second"
    )
    args = parser.parse_args()
    if not 1.0 <= args.seconds <= 600.0:
        parser.error("--seconds: from 1 to 600")
    if not all(1 <= rate <= 1_000_000 for rate in args.rates):
        parser.error("--rates: from 1 to 1,000,000 a second")
    with tempfile.TemporaryDirectory(prefix="hostile-rsp-") as folder:
        robot = Robot(Path(folder))
        try:
            print(
                f"rcmlconf robot {MODEL.name} (pid {robot.process.pid}, T = 5 ms) on "
                f"{robot.address[0]}:{robot.address[1]}; the local system in this process, the "
                f"flood from {ATTACKER}, niced; {args.seconds:g} s a row\n"
            )
            print(HEAD)
            rows = asyncio.run(run(robot, args.rates, args.seconds))
        finally:
            robot.stop()
        alone = rows[0]
        print(f"\nanchor: the alone row (UPLINK gap p99 {alone.gap_p99:.1f} ms); under a flood:")
        for found in rows[1:]:
            ratio = found.gap_p99 / alone.gap_p99 if alone.gap_p99 else float("nan")
            print(
                f"  {found.name:<16}gap p99 x{ratio:.2f}; nothing taken: "
                f"{'yes' if found.old == 0 and not found.closed else 'NO'}; UPLINKs lost: "
                f"{found.lost}; dropped by the kernel at the robot's port (hostile or not): "
                f"{found.drops}"
            )
        print(f"\nthe robot's standard error, last lines:\n{robot.log()[-600:]}")


if __name__ == "__main__":
    main()
