"""The connections' work, a slice of time a turn of the loop, shared fairly among peer addresses
(D-RCTP-32).

asyncio runs in one turn the callback of every socket that is ready, and then the timers due,
among them the streams' beats. When hundreds of connections have something at once (a flood's
requests sent together), the turn lasts as long as all of them take: the beats wait that long,
and so does the request of every other peer that came in the same turn. So a connection's work
goes through `Turns`: it is done at once while the turn has spent less than its budget on such
work, and its peer less than its share of it, with none of its peer's work waiting and no more
time had than the others that wait (below); otherwise it waits in its peer's queue (the
connection is not read meanwhile), and the queues are served in the next turns, `budget`
seconds a turn, after the sockets ready in that turn: a request that comes while others wait
finds the turn's budget whole (its peer waiting for nothing), not spent on the queues first.
(Served at the head of the turn, under bench/hostile_load.py's mix, they made a legitimate READ
wait 4 to 6 ms more in the turn that read it.)

The queues are served by fair queuing over CPU time (start-time fair queuing): each peer's work
is stamped with the time it has had, the next piece served is the waiting peer's with the least,
and a peer that begins to wait starts level with the piece served last, or behind it by what it
had since, never ahead with credit saved while idle. An address with a thousand connections is
then served as much as one with one, in time as in turns: a slice of 50 requests costs its peer
fifty times what one request costs another, and a peer that sends one request now and then is
served before the peers that keep the server busy. Nor is a peer that has had more than the
piece served last done at once, within a turn's budget, while others wait: it waits its turn,
and the budget is left to the peers that ask little. (Done at once up to their share, ten
attacking addresses took the turn's budget before a legitimate READ that came in the same
turn, and it waited 4 to 12 ms for the queues.)

Only while some peer waits is there a debt to count: when no one waits no one is behind (the
virtual time moves to the last finish at the end of a busy period, as start-time fair queuing
has it), so work done at once while the server had time to spare never counts against its peer
later. Counted, a legitimate client's requests of a quiet minute made its READ wait, once a
flood came, until the flood had had as much time: 240 ms (bench/hostile_load.py --turns).
"""

from __future__ import annotations

import asyncio
import heapq
import time
from collections import deque
from collections.abc import Callable
from itertools import count

Work = Callable[[], None]
#: Peers remembered past the clock before those already behind it are forgotten.
FORGET_AFTER = 256


class Turns:
    __slots__ = (
        "_budget",
        "_clock",
        "_counting",
        "_draining",
        "_finished",
        "_loop",
        "_order",
        "_queues",
        "_share",
        "_spent",
        "_tags",
        "_used",
    )

    def __init__(self, loop: asyncio.AbstractEventLoop, budget: float, share: float) -> None:
        self._loop = loop
        self._budget = budget
        self._share = share
        #: CPU seconds of work done since the turn's count began (reset at the head of the next),
        #: in all and by peer.
        self._spent = 0.0
        self._used: dict[str, float] = {}
        self._counting = False
        #: Peer address -> its work waiting, in order.
        self._queues: dict[str, deque[Work]] = {}
        #: The waiting peers by their time served (fair queuing's virtual time), the least
        #: first, one entry each; and the time of the piece served last.
        self._tags: list[tuple[float, int, str]] = []
        self._clock = 0.0
        #: Peers not waiting, and the time stamp their work had reached (while it is ahead of
        #: the clock: forgotten once behind it, as it would count for nothing).
        self._finished: dict[str, float] = {}
        self._order = count()
        self._draining = False

    @property
    def waiting(self) -> int:
        return sum(len(queue) for queue in self._queues.values())

    def run(self, peer: str, work: Work) -> bool:
        """Do `work` now (True), or queue it for a next turn under `peer` (False)."""
        if (
            peer in self._queues
            or self._spent >= self._budget
            or self._used.get(peer, 0.0) >= self._share
            or self._finished.get(peer, 0.0) > self._clock  # ahead of those that wait
        ):
            self.later(peer, work)
            return False
        took = self._do(peer, work)
        if self._tags:  # others wait: this is time they did not have
            self._finished[peer] = self._start(peer) + took
        return True

    def _start(self, peer: str) -> float:
        """Where `peer`'s next work stands: level with the clock, or behind it."""
        return max(self._clock, self._finished.pop(peer, 0.0))

    def later(self, peer: str, work: Work) -> None:
        """Queue `work` under `peer`: done in a next turn, in its peer's turn."""
        queue = self._queues.get(peer)
        if queue is None:
            queue = self._queues[peer] = deque()
            heapq.heappush(self._tags, (self._start(peer), next(self._order), peer))
        queue.append(work)
        if not self._draining:
            self._next_turn()

    def _do(self, peer: str, work: Work) -> float:
        """Do `work`, counted against the turn and `peer`; the CPU seconds it took."""
        if not self._counting:
            self._counting = True
            self._loop.call_soon(self._new_turn)
        # The thread's CPU time, not the wall's: a piece during which the machine ran another
        # process is not charged for that (a legitimate READ so charged 100 ms waited, after
        # it, until the flood's peers had had as much: 145 to 240 ms, bench/hostile_load.py).
        started = time.thread_time()
        try:
            work()
        finally:
            took = time.thread_time() - started
            self._spent += took
            self._used[peer] = self._used.get(peer, 0.0) + took
        return took

    def _new_turn(self) -> None:
        self._counting = False
        self._spent = 0.0
        self._used.clear()
        clock = self._clock
        if len(self._finished) > FORGET_AFTER:
            self._finished = {p: at for p, at in self._finished.items() if at > clock}

    def _next_turn(self) -> None:
        """`_drain` in the next turn of the loop, after its ready sockets' callbacks: a timer due
        now (asyncio runs the callbacks called soon, then the sockets', then the timers due)."""
        self._draining = True
        self._loop.call_at(self._loop.time(), self._drain)

    def _drain(self) -> None:
        """After a turn's sockets: the least served waiting peer's next piece of work, again
        and again, until the budget is spent (one at least, so that the queues always move
        on)."""
        self._draining = False
        queues, tags = self._queues, self._tags
        done = False
        try:
            while tags and (not done or self._spent < self._budget):
                served, order, peer = heapq.heappop(tags)
                queue = queues[peer]
                work = queue.popleft()
                if not queue:
                    del queues[peer]
                self._clock = served
                done = True
                took = 0.0
                try:
                    took = self._do(peer, work)
                finally:
                    if queue:  # behind the peers served less
                        heapq.heappush(tags, (served + took, order, peer))
                    else:
                        self._finished[peer] = served + took
        finally:  # even past a piece of work that raised (the loop's handler logs it)
            if not tags:  # the busy period is over: every peer level again
                self._finished.clear()
            elif not self._draining:
                self._next_turn()
