"""What the reference server refuses, so that one peer cannot degrade or block the others
(specs/rctp-2.0.md D-RCTP-32, R-RCTP-67).

A peer is an address: every connection from it counts against its caps, whatever its port. The
defaults sit well above R-RCTP-67's floor (64 connections and 32 sessions a peer, 10 s before a
slow connection is closed), so that a client, and a conformance harness running many cases at
once, never meets them; a server behind a NAT that many clients share raises them.
"""

from __future__ import annotations

import errno
import logging
import resource
from collections import Counter
from dataclasses import dataclass
from typing import Generic, Protocol, TypeVar

from rcmlconf.reference.throttled import Throttled

T = TypeVar("T")

log = logging.getLogger("rcmlconf.server")

#: R-RCTP-67's floor: a server that limits its peers serves at least this many of one address.
MIN_CONNECTIONS_PER_PEER = 64
MIN_SESSIONS_PER_PEER = 32
#: ... and closes a slow connection no sooner than this (seconds).
MIN_SLOW_TIMEOUT = 10.0
#: File descriptors kept back from the connection cap: the listeners, the data stream's socket,
#: the log, the connections accepted in a turn of the loop and not yet closed again beyond the
#: cap (`ACCEPTS_A_TURN` a listener), and what the embedding application opens.
RESERVED_FDS = 64
#: Connections a listener accepts in one turn of the loop at most. asyncio accepts as many as
#: the backlog it is given at each wake-up of a listener, and sets each one up before the
#: streams' beats then due can run: a flood of connects is taken a few a turn instead (D-RCTP-32),
#: and waits in the kernel's queue, `LISTEN_QUEUE` long, with the legitimate connects among it.
ACCEPTS_A_TURN = 8
LISTEN_QUEUE = 1024


@dataclass(frozen=True, slots=True)
class ServerLimits:
    """The caps and timeouts of D-RCTP-32, for RCTP's connections and the files' alike."""

    #: Open connections at once, in all: RCTP's control connections and the files server's
    #: together, so that the process stays below its file descriptors. Lowered at start to what
    #: the process may open.
    connections: int = 1024
    #: Open connections of one peer address at once.
    connections_per_peer: int = 256
    #: Sessions of one peer address at once; a CONNECT beyond is answered 503.
    sessions_per_peer: int = 64
    #: A connection that sends no CONNECT this long after it opened, or that has not finished a
    #: request this long after its first byte, is closed (seconds).
    slow_timeout: float = 10.0
    #: One connection's input is handed to its session a piece of `slice_bytes` at a time, for
    #: `slice_time` seconds at most a turn of the loop (a slice): a pipelined burst is answered
    #: in slices, and the other sessions and their streams are served in between. A piece is
    #: done whole, and what it costs depends on the requests it holds: 4 KiB of READs without
    #: a session, 140 of them, took 6 ms, beyond a turn's budget (bench/hostile_load.py
    #: --turns), 512 bytes at most 0.8 ms; while a 4 MiB body's pieces take microseconds each,
    #: and go on together within the slice.
    slice_bytes: int = 512
    slice_time: float = 0.001
    #: A request under way that holds more than `large_bytes` of input (a body D-RCTP-9 allows
    #: up to 4 MiB) is a large one: `large_requests` connections at most hold one at once, the
    #: others are not read meanwhile (TCP holds their peers) and go on in turn. Memory then
    #: grows with these few, about 7.5 MiB each, not with the connections.
    large_bytes: int = 64 * 1024
    large_requests: int = 2
    #: CPU seconds of the connections' work a turn of the loop; the rest waits for the next turns,
    #: shared fairly among the peer addresses (`turns`). A request that comes while a turn is
    #: under way waits for its end: under bench/hostile_load.py's mix the turns took 8 ms of CPU
    #: at the 99th percentile with 4 ms and 5.7 with 2, and a legitimate READ's p99 was 15 ms
    #: against 9.6.
    turn_budget: float = 0.002
    #: CPU seconds of a turn one peer address's connections take, together, before the rest of
    #: their work waits for the next turns: a peer with many connections ready cannot take the
    #: turn's whole budget from another with one.
    peer_share: float = 0.001

    def below_floor(self) -> list[str]:
        """What breaks R-RCTP-67's floor (allowed, for tests; `serve` warns of it)."""
        found = []
        if self.connections_per_peer < MIN_CONNECTIONS_PER_PEER:
            found.append(f"{self.connections_per_peer} connections a peer")
        if self.sessions_per_peer < MIN_SESSIONS_PER_PEER:
            found.append(f"{self.sessions_per_peer} sessions a peer")
        if self.slow_timeout < MIN_SLOW_TIMEOUT:
            found.append(f"a slow connection closed after {self.slow_timeout:g} s")
        return found


#: The defaults, one frozen instance (an argument's default value).
DEFAULT_LIMITS = ServerLimits()


def connection_cap(wanted: int) -> int:
    """`wanted`, or fewer when the process may not open that many files (and sockets) besides
    what it needs for everything else: a cap above the limit would only turn into EMFILE."""
    soft, _hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    if soft == resource.RLIM_INFINITY:
        return wanted
    return max(1, min(wanted, soft - RESERVED_FDS))


class Evictable(Protocol):
    """A connection the table may close to make room (D-RCTP-32)."""

    def evict(self) -> None:
        """Close the connection at once: it has no request to answer."""


class PeerCount:
    """Open connections, in all and by peer address, against their caps; and those without a
    session, by address and oldest first, of which a full table closes one to take a new one
    (D-RCTP-32): one of the address that holds the most, so that a peer flooding the table with
    idle connections makes room with its own.

    Each change is O(1): the addresses are kept in buckets by how many connections without a
    session they hold, and the fullest bucket is known (a count moves by one at a time)."""

    __slots__ = (
        "_by_peer",
        "_evicted_log",
        "_fullest",
        "_idle",
        "_ranked",
        "_refused_log",
        "cap",
        "evicted",
        "per_peer",
        "total",
    )

    def __init__(self, cap: int, per_peer: int) -> None:
        self.cap = cap
        self.per_peer = per_peer
        self.total = 0
        #: Connections closed to make room, since the start.
        self.evicted = 0
        self._by_peer: Counter[str] = Counter()
        #: Each address's connections without a session, oldest first (a dict for an ordered
        #: set); the addresses by how many of them they hold; the most any address holds.
        self._idle: dict[str, dict[Evictable, None]] = {}
        self._ranked: dict[int, dict[str, None]] = {}
        self._fullest = 0
        #: Refusals and evictions, a line in the log now and then (`Throttled`).
        self._refused_log = Throttled(log, "connections refused")
        self._evicted_log = Throttled(log, "connections closed to make room")

    def admit(self, peer: str, connection: Evictable, now: float) -> bool:
        """Count a new connection of `peer`, without a session, making room if the table is
        full; or refuse it (False: close it at once): beyond the address's cap, or the table
        full of sessions."""
        if self._by_peer[peer] >= self.per_peer or (
            self.total >= self.cap and not self._evict(now)
        ):
            self._refused_log.happened(now, f"{peer} (a cap of D-RCTP-32)")
            return False
        self.total += 1
        self._by_peer[peer] += 1
        self._add_idle(peer, connection)
        return True

    def seated(self, peer: str, connection: Evictable) -> None:
        """`connection` holds a session now: it is never closed to make room."""
        self._drop_idle(peer, connection)

    def leave(self, peer: str, connection: Evictable) -> None:
        self.total -= 1
        self._by_peer[peer] -= 1
        if self._by_peer[peer] <= 0:
            del self._by_peer[peer]
        self._drop_idle(peer, connection)

    def _evict(self, now: float) -> bool:
        """Close the oldest connection without a session of the address holding the most of
        them; False if every connection holds a session. The closed one counts until it
        leaves, as every connection does while its descriptor is open."""
        if not self._fullest:
            return False
        peer = next(iter(self._ranked[self._fullest]))
        connection = next(iter(self._idle[peer]))
        self._drop_idle(peer, connection)
        self.evicted += 1
        self._evicted_log.happened(now, f"{peer} (no session, the table full: D-RCTP-32)")
        connection.evict()
        return True

    def _add_idle(self, peer: str, connection: Evictable) -> None:
        idle = self._idle.setdefault(peer, {})
        idle[connection] = None
        self._move(peer, len(idle) - 1, len(idle))

    def _drop_idle(self, peer: str, connection: Evictable) -> None:
        idle = self._idle.get(peer)
        if idle is None or connection not in idle:
            return
        del idle[connection]
        if not idle:
            del self._idle[peer]
        self._move(peer, len(idle) + 1, len(idle))

    def _move(self, peer: str, held: int, now: int) -> None:
        """`peer` holds `now` connections without a session, one more or one less than `held`:
        it moves to that bucket, and the fullest is the fullest still."""
        if held:
            bucket = self._ranked[held]
            del bucket[peer]
            if not bucket:
                del self._ranked[held]
                if self._fullest == held:
                    self._fullest = now
        if now:
            self._ranked.setdefault(now, {})[peer] = None
            self._fullest = max(self._fullest, now)


#: What an accept fails with when the process or the system is out of something: asyncio logs
#: these with a traceback and tries again a second later; the server says it in one line.
ACCEPT_ERRNOS = frozenset({errno.EMFILE, errno.ENFILE, errno.ENOBUFS, errno.ENOMEM})


class Places(Generic[T]):
    """At most `count` holders at once; the others wait, and take a place in turn as one is
    left (D-RCTP-32: the connections with a large request under way)."""

    __slots__ = ("_holders", "_waiting", "count")

    def __init__(self, count: int) -> None:
        self.count = count
        self._holders: set[T] = set()
        #: In the order they came (a dict for an ordered set).
        self._waiting: dict[T, None] = {}

    @property
    def held(self) -> int:
        return len(self._holders)

    @property
    def waiting(self) -> int:
        return len(self._waiting)

    def take(self, item: T) -> bool:
        """Whether `item` holds a place (now, or already); if not, it waits in turn."""
        if item in self._holders:
            return True
        if len(self._holders) < self.count and not self._waiting:
            self._holders.add(item)
            return True
        self._waiting[item] = None
        return False

    def leave(self, item: T) -> list[T]:
        """`item` holds no place and waits for none; the waiting ones that took the place, in
        turn."""
        self._waiting.pop(item, None)
        if item not in self._holders:
            return []
        self._holders.discard(item)
        admitted = []
        while self._waiting and len(self._holders) < self.count:
            first = next(iter(self._waiting))
            del self._waiting[first]
            self._holders.add(first)
            admitted.append(first)
        return admitted
