"""One direction of a probe's UDP path through the case's impairment (rcmlconf.impair): what goes
in is lost, corrupted, duplicated or held back by an `ImpairedChannel`, and handed on when due by
a timer of the event loop. Every probe with UDP flows (the data stream's, the RSP probes) puts
what it sends, and the stream probe what it receives, through one.

What comes out is handed on with its time: the time it went in (a received datagram's arrival)
when nothing impairs the path, else the loop's clock as the impairment lets it through."""

from __future__ import annotations

import asyncio
from collections.abc import Callable

from rcmlconf.conformance.transcript import Address
from rcmlconf.impair import ImpairedChannel


class ImpairedPath:
    """One direction between the socket and the case: the impairment's channel on a loop
    timer, or nothing at all. Addresses ride beside the bytes, keyed by a prefix the channel
    carries (a duplicate keeps its original's)."""

    def __init__(
        self,
        channel: ImpairedChannel | None,
        deliver: Callable[[bytes, Address, int, float], None],
        loop: asyncio.AbstractEventLoop,
    ) -> None:
        self.channel = channel
        self._deliver = deliver
        self._loop = loop
        self._addresses: dict[int, Address] = {}
        self._key = 0
        self._timer: asyncio.TimerHandle | None = None
        #: Lost since the last delivery.
        self._lost = 0

    def put(self, data: bytes, address: Address, at: float | None = None) -> str:
        """Into the path at `at` (by default now); what befell it when no intact copy will come
        out ("lost", "corrupted"), else "". A corrupted copy does come out (its receiver drops
        it)."""
        channel = self.channel
        if channel is None:
            self._deliver(data, address, 0, self._loop.time() if at is None else at)
            return ""
        self._key += 1
        self._addresses[self._key] = address
        counts = channel.counts
        lost, corrupted, duplicated = counts.lost, counts.corrupted, counts.duplicated
        channel.send(self._key.to_bytes(4, "big") + data, self._loop.time())
        gone = counts.lost > lost
        self._lost += gone
        self._due()
        if gone:
            return "lost"
        if counts.corrupted > corrupted and counts.duplicated == duplicated:
            return "corrupted"
        return ""

    def _due(self) -> None:
        assert self.channel is not None
        now = self._loop.time()
        for item in self.channel.due(now):
            key = int.from_bytes(item[:4], "big")
            address = self._addresses.get(key) or self._addresses[self._key]
            lost, self._lost = self._lost, 0
            self._deliver(item[4:], address, lost, now)
        if self._timer is not None:
            self._timer.cancel()
            self._timer = None
        when = self.channel.get_timer()
        if when is not None:
            self._timer = self._loop.call_at(when, self._due)

    def close(self, *, flush: bool = False) -> None:
        """No more deliveries: what the channel holds is dropped, or with `flush` handed on at
        once, in order (a probe's last packets, before the word that ends its session)."""
        if self._timer is not None:
            self._timer.cancel()
            self._timer = None
        if self.channel is None:
            return
        if not flush:
            self.channel.discard()
            return
        now = self._loop.time()
        for item in self.channel.flush():
            key = int.from_bytes(item[:4], "big")
            address = self._addresses.get(key) or self._addresses[self._key]
            self._deliver(item[4:], address, 0, now)
