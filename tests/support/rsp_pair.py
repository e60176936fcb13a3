"""A local system and a robot joined in memory, on a simulated clock, with seeded loss,
duplication and reordering: the sans-IO endpoints exactly as the adapters drive them, minus
sockets."""

from __future__ import annotations

import random
from dataclasses import dataclass, field

from rcmlconf.rsp.model import RobotModel
from rcmlconf.rsp.session import events
from rcmlconf.rsp.session.local import LocalEndpoint
from rcmlconf.rsp.session.robot import RobotEndpoint

LOCAL_ADDR = ("127.0.0.1", 40000)
#: One way, seconds.
DELAY = 0.005


@dataclass
class Pair:
    model: RobotModel
    local: LocalEndpoint
    robot: RobotEndpoint
    loss: float = 0.0
    duplicate: float = 0.0
    reorder: float = 0.0
    seed: int = 0
    now: float = 0.0
    #: (arrival time, order, to robot?, datagram)
    flight: list[tuple[float, int, bool, bytes]] = field(default_factory=list)
    local_events: list[events.Event] = field(default_factory=list)
    robot_events: list[events.Event] = field(default_factory=list)
    sent_down: list[bytes] = field(default_factory=list)
    sent_up: list[bytes] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.rng = random.Random(self.seed)
        self._order = 0

    def _post(self, data: bytes, to_robot: bool) -> None:
        (self.sent_down if to_robot else self.sent_up).append(data)
        if self.rng.random() < self.loss:
            return
        copies = 2 if self.rng.random() < self.duplicate else 1
        for _ in range(copies):
            held = self.rng.random() < self.reorder
            delay = DELAY + (3 * DELAY * self.rng.random() if held else 0)
            self._order += 1
            self.flight.append((self.now + delay, self._order, to_robot, data))

    def _flush(self) -> None:
        for data in self.local.datagrams_to_send(self.now):
            self._post(data, True)
        for data, addr in self.robot.datagrams_to_send(self.now):
            assert addr == LOCAL_ADDR
            self._post(data, False)
        while (event := self.local.next_event()) is not None:
            self.local_events.append(event)
        while (event := self.robot.next_event()) is not None:
            self.robot_events.append(event)

    def run_until(self, end: float) -> None:
        """Deliver and fire timers in time order until `end` (bounded: the clock only grows)."""
        self._flush()
        for _ in range(10_000_000):
            times = [t for t in (self.local.get_timer(), self.robot.get_timer()) if t is not None]
            if self.flight:
                times.append(min(self.flight)[0])
            next_time = max(min(times, default=end), self.now)
            if next_time > end or not times:
                self.now = end
                return
            self.now = next_time
            due = sorted(f for f in self.flight if f[0] <= self.now)
            self.flight = [f for f in self.flight if f[0] > self.now]
            for _, _, to_robot, data in due:
                if to_robot:
                    self.robot.receive_datagram(data, LOCAL_ADDR, self.now)
                else:
                    self.local.receive_datagram(data, self.now)
            self.local.handle_timer(self.now)
            self.robot.handle_timer(self.now)
            self._flush()
        raise AssertionError("the endpoints' timers never moved past the clock")


def open_pair(
    model: RobotModel,
    local: LocalEndpoint | None = None,
    robot: RobotEndpoint | None = None,
    *,
    loss: float = 0.0,
    duplicate: float = 0.0,
    reorder: float = 0.0,
    seed: int = 0,
) -> Pair:
    """A pair whose local system has sent its HELLO at 0."""
    local = local or LocalEndpoint(model, nonce=b"n" * 16)
    pair = Pair(model, local, robot or RobotEndpoint(model), loss, duplicate, reorder, seed)
    local.connect(0.0)
    return pair
