"""One direction of an impaired datagram path, without I/O: datagrams in, and out when due.

`ImpairedChannel` applies an `Impairment` (see its docstring for what each setting does) to the
datagrams `send` gives it; `due(now)` hands back those whose delivery time has come, and
`get_timer()` says when the next one will. Time is whatever the caller says it is (a simulation's
clock, or the event loop's), and nothing happens between calls.

Determinism: every random draw comes from the channel's own `random.Random(seed)`, seven draws a
datagram whatever the settings and whatever `now` is, so the same sequence of datagrams meets the
same fates (lost, duplicated, corrupted and which bit, held back) for the same seed, and the same
delivery times when it is sent at the same times. Changing only the delay leaves the losses as
they were. The two directions of a flow, and the flows of a proxy, must not share a stream of
draws: `derive_seed` makes each its own seed from the run's seed (`channel_pair`).
"""

from __future__ import annotations

import hashlib
import heapq
import random
from dataclasses import dataclass, fields, replace

from rcmlconf.impair.spec import Impairment

__all__ = [
    "DEFAULT_LIMIT",
    "Counts",
    "ImpairedChannel",
    "channel_pair",
    "derive_seed",
]

#: At most this many datagrams are held by a channel by default; more are dropped and counted.
DEFAULT_LIMIT = 10_000


@dataclass(slots=True)
class Counts:
    """What happened to one direction's datagrams (or several directions', summed with `+`).

    Held datagrams are those counted in neither `delivered`, `dropped` nor `discarded` yet::

        sent - lost + duplicated == delivered + dropped + discarded + held
    """

    #: Datagrams given to `send`.
    sent: int = 0
    #: Lost by the impairment (`loss`, `burst`).
    lost: int = 0
    #: Extra copies made (`duplicate`).
    duplicated: int = 0
    #: Held back by `gap` (`reorder`), whether or not a later datagram then overtook them.
    reordered: int = 0
    #: Had one bit flipped (`corrupt`).
    corrupted: int = 0
    #: Handed back by `due` or `flush`.
    delivered: int = 0
    #: Dropped because the channel already held its limit.
    dropped: int = 0
    #: Held when the channel was emptied by `discard`.
    discarded: int = 0

    def __add__(self, other: Counts) -> Counts:
        return Counts(*(getattr(self, f.name) + getattr(other, f.name) for f in fields(self)))

    def copy(self) -> Counts:
        return replace(self)


def derive_seed(seed: int, *path: int | str) -> int:
    """A seed for one part of a run (a flow, a direction), from the run's seed.

    The first 8 bytes, big-endian, of SHA-256 over `rcmlconf.impair/SEED/PART/PART...` in
    decimal and text: the same in every process and Python version (unlike `hash`), and
    unrelated between neighbouring parts. `channel_pair` uses `(flow, "forward")` and
    `(flow, "backward")`.
    """
    text = "/".join(["rcmlconf.impair", str(seed), *(str(part) for part in path)])
    return int.from_bytes(hashlib.sha256(text.encode()).digest()[:8], "big")


def channel_pair(
    impairment: Impairment, seed: int, flow: int = 0, *, limit: int = DEFAULT_LIMIT
) -> tuple[ImpairedChannel, ImpairedChannel]:
    """The two directions of flow number `flow` of a run: forward (from the side that spoke
    first, a proxy's client) with seed `derive_seed(seed, flow, "forward")`, and backward with
    `derive_seed(seed, flow, "backward")`."""
    return (
        ImpairedChannel(impairment, derive_seed(seed, flow, "forward"), limit=limit),
        ImpairedChannel(impairment, derive_seed(seed, flow, "backward"), limit=limit),
    )


class ImpairedChannel:
    """One direction of a path with an `Impairment`, in the caller's time (sans-IO).

    `send(datagram, now)`, then `due(now)` at `get_timer()` or any time after. Times must not go
    backwards. With `Impairment()` every datagram is due at once, unchanged and in order.
    """

    __slots__ = (
        "_bad",
        "_enter_bad",
        "_floor",
        "_gap",
        "_heap",
        "_leave_bad",
        "_rng",
        "_seq",
        "counts",
        "impairment",
        "limit",
        "seed",
    )

    def __init__(self, impairment: Impairment, seed: int, *, limit: int = DEFAULT_LIMIT) -> None:
        if limit < 1:
            raise ValueError(f"limit must be at least 1, not {limit}")
        self.impairment = impairment
        self.seed = seed
        self.limit = limit
        self.counts = Counts()
        self._rng = random.Random(seed)
        #: (delivery time, sequence number, datagram): the sequence number keeps ties in order.
        self._heap: list[tuple[float, int, bytes]] = []
        self._seq = 0
        #: The delivery time of the last datagram not held back: none may come before it.
        self._floor = float("-inf")
        self._gap = impairment.reorder_gap
        # The Gilbert model: enter Bad with this probability a datagram, leave it with that.
        loss, burst = impairment.loss, impairment.burst
        self._leave_bad = 1.0 / burst if burst is not None else 1.0 - loss
        self._enter_bad = loss * self._leave_bad / (1.0 - loss) if loss < 1.0 else 1.0
        self._bad = self._rng.random() < loss  # the first datagram's state, as in the long run

    @property
    def held(self) -> int:
        """Datagrams waiting for their delivery time."""
        return len(self._heap)

    def send(self, datagram: bytes, now: float) -> None:
        """Take one datagram at time `now`: it is lost, or due later (maybe twice)."""
        rng = self._rng
        draws = [rng.random() for _ in range(7)]
        u_loss, u_duplicate, u_corrupt, u_bit, u_reorder, u_delay, u_copy_delay = draws
        imp = self.impairment
        counts = self.counts
        counts.sent += 1
        if self._lost(u_loss):
            counts.lost += 1
            return
        data = datagram
        if u_corrupt < imp.corrupt and datagram:
            bit = int(u_bit * len(datagram) * 8)
            flipped = bytearray(datagram)
            flipped[bit >> 3] ^= 1 << (bit & 7)
            data = bytes(flipped)
            counts.corrupted += 1
        at = self._in_order(now, u_delay)
        if u_reorder < imp.reorder:
            counts.reordered += 1
            self._push(at + self._gap, data)
        else:
            self._floor = at
            self._push(at, data)
        if u_duplicate < imp.duplicate:
            counts.duplicated += 1
            at = self._in_order(now, u_copy_delay)
            self._floor = at
            self._push(at, bytes(datagram))

    def due(self, now: float) -> list[bytes]:
        """The datagrams due at `now` or before, in delivery order; they are no longer held."""
        heap = self._heap
        out: list[bytes] = []
        while heap and heap[0][0] <= now:
            out.append(heapq.heappop(heap)[2])
        self.counts.delivered += len(out)
        return out

    def get_timer(self) -> float | None:
        """When the next datagram is due; None when none is held."""
        return self._heap[0][0] if self._heap else None

    def flush(self) -> list[bytes]:
        """Every held datagram at once, in delivery order (counted delivered): for a close."""
        out = [item[2] for item in sorted(self._heap)]
        self._heap.clear()
        self.counts.delivered += len(out)
        return out

    def discard(self) -> int:
        """Forget every held datagram (counted discarded); how many there were."""
        n = len(self._heap)
        self._heap.clear()
        self.counts.discarded += n
        return n

    def _lost(self, u: float) -> bool:
        loss = self.impairment.loss
        if loss <= 0.0 or loss >= 1.0:
            return loss >= 1.0
        if self.impairment.burst is None:
            return u < loss
        self._bad = u >= self._leave_bad if self._bad else u < self._enter_bad
        return self._bad

    def _in_order(self, now: float, u: float) -> float:
        imp = self.impairment
        delay = imp.delay + imp.jitter * (2.0 * u - 1.0) if imp.jitter else imp.delay
        at = now + delay if delay > 0.0 else now
        return at if at > self._floor else self._floor

    def _push(self, at: float, datagram: bytes) -> None:
        if len(self._heap) >= self.limit:
            self.counts.dropped += 1
            return
        heapq.heappush(self._heap, (at, self._seq, datagram))
        self._seq += 1
