"""A local system and a robot on a simulated clock, joined by an impaired path each way.

Everything is sans-IO and deterministic for a seed: the endpoints and the channels take the
clock's `now`, their randomness (session IDs, nonces, the channels' draws) comes from seeds
derived from the run's seed, and nothing reads the wall clock.

- `Clock`: the event loop. It asks its parts when they next need to run (`get_timer`), moves to
  the earliest, and runs in a fixed order: deliveries, periodic tasks (an application's control
  period), then the endpoints' timers. Periodic tasks run at `start + k x period` exactly, and a
  task within a microsecond of an endpoint's beat runs first, so an application's values always
  make the beat they were written for.
- `Path`: one direction: a FIFO bottleneck of `bandwidth` bits/s (each packet is serialised
  after the one before it, with its IP and transport headers) feeding an `ImpairedChannel`
  (loss, delay, jitter ...). `bandwidth=None` serialises in no time.
- `RspSimulation`: a `LocalEndpoint` and a `RobotEndpoint` over a `Path` each way; the robot runs
  a control loop every period: the motion filter's output (`effectors(now)`) to the body, the
  body's sensors and monitors back (`set_state`).
"""

from __future__ import annotations

import hashlib
import math
import random
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path as FilePath

from rcmlconf.impair import Counts, ImpairedChannel, Impairment, derive_seed
from rcmlconf.reference.rsp.cubo import CuboBody
from rcmlconf.rsp.codec import Encryption
from rcmlconf.rsp.model import RobotModel
from rcmlconf.rsp.session import events
from rcmlconf.rsp.session.local import LocalEndpoint
from rcmlconf.rsp.session.robot import RobotEndpoint

#: Nothing happens to a datagram.
NO_IMPAIRMENT = Impairment()
#: CUBO's robot model (D-RSP-8), which both experiments run.
CUBO_MODEL = (
    FilePath(__file__).resolve().parents[1] / "reference" / "robots" / "cubo" / "cubo.rmodel"
)
#: IPv4 (20) and UDP (8) headers: what an RSP datagram costs on the wire beyond its bytes.
UDP_OVERHEAD = 28
#: The local system's address, as the robot sees it (TEST-NET-1, RFC 5737).
LOCAL_ADDR = ("192.0.2.1", 40000)
#: A task this close to a timer runs first (float sums of periods drift by far less).
EPSILON = 1e-6
#: A run that takes more steps than this is stuck (a timer that never moves).
MAX_STEPS = 50_000_000


@dataclass(slots=True)
class _Task:
    period: float
    start: float
    callback: Callable[[float], None]
    ticks: int = 0

    @property
    def next(self) -> float:
        return self.start + self.ticks * self.period


class Clock:
    """The simulated clock and its periodic tasks; subclasses join their parts to it."""

    def __init__(self) -> None:
        self.now = 0.0
        self._tasks: list[_Task] = []

    def every(self, period: float, callback: Callable[[float], None], start: float) -> None:
        """Call `callback(now)` at `start`, `start + period`, ... (tasks in the order added)."""
        self._tasks.append(_Task(period, start, callback))

    def run_until(self, end: float, until: Callable[[], bool] | None = None) -> None:
        """Run everything due up to `end` in time order; stop early once `until()` holds."""
        for _ in range(MAX_STEPS):
            times = [t for t in self._timers() if t is not None]
            times.extend(task.next for task in self._tasks)
            upcoming = min(times, default=math.inf)
            if upcoming > end:
                self.now = max(self.now, end)
                return
            now = self.now = max(self.now, upcoming)
            self._deliver(now)
            for task in self._tasks:
                while task.next <= now + EPSILON:
                    task.ticks += 1
                    task.callback(now)
            self._fire(now)
            if until is not None and until():
                return
        raise RuntimeError("the simulation's timers never moved past the clock")

    # -- the parts: what subclasses provide ----------------------------------------------------

    def _timers(self) -> list[float | None]:
        return []

    def _deliver(self, now: float) -> None:
        """Hand over what the paths deliver at `now`."""

    def _fire(self, now: float) -> None:
        """Run the endpoints' timers due at `now`, and send what they have."""


class Path:
    """One direction: a bottleneck link of `bandwidth` bits/s, then an `ImpairedChannel`.

    A packet takes `(len + overhead) x 8 / bandwidth` seconds to serialise, after the packets
    before it (a FIFO without limit: the sender's queue and the bottleneck's are one); then the
    channel loses, delays or reorders it."""

    def __init__(
        self, impairment: Impairment, seed: int, *, bandwidth: float | None, overhead: int
    ) -> None:
        self.channel = ImpairedChannel(impairment, seed)
        self.bandwidth = bandwidth
        self.overhead = overhead
        self._queue: deque[tuple[float, bytes]] = deque()
        self._free = -math.inf
        #: Packets and bytes (with overhead) given to the path.
        self.packets = 0
        self.bytes = 0

    def send(self, data: bytes, now: float, size: int | None = None) -> None:
        """Queue a packet at `now`; `size` is its bytes on the wire without overhead (default:
        its length)."""
        wire = (len(data) if size is None else size) + self.overhead
        self.packets += 1
        self.bytes += wire
        if self.bandwidth is None:
            self.channel.send(data, now)
            return
        start = max(now, self._free)
        self._free = start + wire * 8 / self.bandwidth
        self._queue.append((self._free, data))

    def get_timer(self) -> float | None:
        queued = self._queue[0][0] if self._queue else None
        held = self.channel.get_timer()
        if queued is None:
            return held
        return queued if held is None else min(queued, held)

    def due(self, now: float) -> list[bytes]:
        """The packets delivered at `now` or before, in order."""
        queue = self._queue
        while queue and queue[0][0] <= now:
            departed, data = queue.popleft()
            self.channel.send(data, departed)
        return self.channel.due(now)

    @property
    def backlog(self) -> float:
        """Seconds of serialisation still queued behind the bottleneck (0 without one)."""
        return 0.0 if not self._queue else self._free - self._queue[0][0]

    @property
    def counts(self) -> Counts:
        return self.channel.counts


@dataclass(slots=True)
class Traffic:
    """What one side put on its path: every packet's send time and bytes (without overhead)."""

    times: list[float] = field(default_factory=list)
    sizes: list[int] = field(default_factory=list)
    types: list[int] = field(default_factory=list)


def cubo_model() -> RobotModel:
    """CUBO's robot model, loaded and checked."""
    from rcmlconf.validate.validator import load_robot_model

    return load_robot_model(CUBO_MODEL)


def psk_for(seed: int) -> bytes:
    """The pre-shared key of a simulated robot (D-RSP-21): 32 bytes from the seed."""
    return hashlib.sha256(f"rcmlconf.experiments/psk/{seed}".encode()).digest()


class RspSimulation(Clock):
    """A local system and a robot with a simulated CUBO over an impaired path each way."""

    def __init__(
        self,
        model: RobotModel,
        *,
        downlink: Impairment = NO_IMPAIRMENT,
        uplink: Impairment = NO_IMPAIRMENT,
        seed: int = 0,
        period: float | None = None,
        encryption: Encryption = Encryption.NONE,
        bandwidth: float | None = None,
        body: CuboBody | None = None,
        control_period: float | None = None,
    ) -> None:
        super().__init__()
        self.model = model
        psk = psk_for(seed) if encryption is not Encryption.NONE else None
        nonce = hashlib.sha256(f"rcmlconf.experiments/nonce/{seed}".encode()).digest()[:16]
        self.local = LocalEndpoint(
            model, period=period, encryption=encryption, psk=psk, nonce=nonce
        )
        self._robot_random = random.Random(derive_seed(seed, "robot"))
        self.robot = RobotEndpoint(
            model, encryptions=frozenset({encryption}), psk=psk, random=self._robot_random.randbytes
        )
        self.down = Path(
            downlink, derive_seed(seed, "downlink"), bandwidth=bandwidth, overhead=UDP_OVERHEAD
        )
        self.up = Path(
            uplink, derive_seed(seed, "uplink"), bandwidth=bandwidth, overhead=UDP_OVERHEAD
        )
        self.body = body
        #: What each side sent, packet by packet.
        self.sent_down = Traffic()
        self.sent_up = Traffic()
        #: Called with every event of each endpoint, as it comes.
        self.local_listeners: list[Callable[[events.Event, float], None]] = []
        self.robot_listeners: list[Callable[[events.Event, float], None]] = []
        #: The clock time of the local system's first packet: its timestamps count from it.
        self.local_epoch: float | None = None
        self.opened_at: float | None = None
        if body is not None:
            tick = model.period if control_period is None else control_period
            self.every(tick, self._control, 0.0)

    def open(self, timeout: float = 5.0) -> float:
        """Send HELLO now and run until the session is open; the time it opened."""
        self.local_epoch = self.now
        self.local.connect(self.now)
        self._flush(self.now)
        self.run_until(self.now + timeout, lambda: self.opened_at is not None)
        if self.opened_at is None:
            raise RuntimeError(f"no session within {timeout} s")
        return self.opened_at

    def _control(self, now: float) -> None:
        """The robot's control period: effectors out, the body on, sensors and monitors back."""
        body = self.body
        assert body is not None
        body.apply(self.robot.effectors(now), now)
        for name, values in body.sensors(now, self.robot.reporting()).items():
            self.robot.set_state(name, values)

    # -- the clock's parts ---------------------------------------------------------------------

    def _timers(self) -> list[float | None]:
        return [
            self.local.get_timer(),
            self.robot.get_timer(),
            self.down.get_timer(),
            self.up.get_timer(),
        ]

    def _deliver(self, now: float) -> None:
        for data in self.down.due(now):
            self.robot.receive_datagram(data, LOCAL_ADDR, now)
        for data in self.up.due(now):
            self.local.receive_datagram(data, now)

    def _fire(self, now: float) -> None:
        timer = self.local.get_timer()
        if timer is not None and timer <= now:
            self.local.handle_timer(now)
        timer = self.robot.get_timer()
        if timer is not None and timer <= now:
            self.robot.handle_timer(now)
        self._flush(now)

    def _flush(self, now: float) -> None:
        for data in self.local.datagrams_to_send(now):
            _record(self.sent_down, now, data)
            self.down.send(data, now)
        for data, _ in self.robot.datagrams_to_send(now):
            _record(self.sent_up, now, data)
            self.up.send(data, now)
        while (event := self.local.next_event()) is not None:
            if isinstance(event, events.SessionOpened) and self.opened_at is None:
                self.opened_at = now
            for listener in self.local_listeners:
                listener(event, now)
        while (event := self.robot.next_event()) is not None:
            for listener in self.robot_listeners:
                listener(event, now)


def _record(traffic: Traffic, now: float, data: bytes) -> None:
    traffic.times.append(now)
    traffic.sizes.append(len(data))
    traffic.types.append(data[4] if len(data) > 4 else 0)
