"""The connections' work, a slice of time a turn of the loop, peer by peer (D-RCTP-32).

asyncio runs in one turn the callback of every socket that is ready, and then the timers due,
among them the streams' beats. When hundreds of connections have something at once (a flood's
requests sent together), the turn lasts as long as all of them take: the beats wait that long,
and so does the request of every other peer that came in the same turn. So a connection's work
goes through `Turns`: it is done at once while the turn has spent less than its budget on such
work and nothing waits; otherwise it waits in its peer's queue (the connection is not read
meanwhile), and the queues are served at the head of the next turns, `budget` seconds a turn, one
piece of work of each peer in turn. A peer with a thousand connections is then served as often
as a peer with one, and a turn ends, with its beats, within about the budget.
"""

from __future__ import annotations

import asyncio
import time
from collections import deque
from collections.abc import Callable

Work = Callable[[], None]


class Turns:
    __slots__ = ("_budget", "_counting", "_draining", "_loop", "_queues", "_spent")

    def __init__(self, loop: asyncio.AbstractEventLoop, budget: float) -> None:
        self._loop = loop
        self._budget = budget
        #: Seconds of work done since the turn's count began (reset at the head of the next).
        self._spent = 0.0
        self._counting = False
        #: Peer address -> its work waiting, in order; the peers in the order they are served.
        self._queues: dict[str, deque[Work]] = {}
        self._draining = False

    @property
    def waiting(self) -> int:
        return sum(len(queue) for queue in self._queues.values())

    def run(self, peer: str, work: Work) -> bool:
        """Do `work` now (True), or queue it for a next turn under `peer` (False)."""
        if self._queues or self._spent >= self._budget:
            self.later(peer, work)
            return False
        self._do(work)
        return True

    def later(self, peer: str, work: Work) -> None:
        """Queue `work` under `peer`: done in a next turn, in its peer's turn."""
        queue = self._queues.get(peer)
        if queue is None:
            queue = self._queues[peer] = deque()
        queue.append(work)
        if not self._draining:
            self._draining = True
            self._loop.call_soon(self._drain)

    def _do(self, work: Work) -> None:
        if not self._counting:
            self._counting = True
            self._loop.call_soon(self._new_turn)
        started = time.perf_counter()
        try:
            work()
        finally:
            self._spent += time.perf_counter() - started

    def _new_turn(self) -> None:
        self._counting = False
        self._spent = 0.0

    def _drain(self) -> None:
        """At the head of a turn: one piece of work of each peer in turn, until the budget is
        spent (one at least, so that the queues always move on)."""
        self._draining = False
        queues = self._queues
        done = False
        try:
            while queues and (not done or self._spent < self._budget):
                peer = next(iter(queues))
                queue = queues.pop(peer)
                work = queue.popleft()
                if queue:
                    queues[peer] = queue  # behind the other peers
                done = True
                self._do(work)
        finally:  # even past a piece of work that raised (the loop's handler logs it)
            if queues and not self._draining:
                self._draining = True
                self._loop.call_soon(self._drain)
