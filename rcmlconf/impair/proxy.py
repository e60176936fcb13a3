"""An impairing UDP proxy on asyncio: sans-IO channels between real sockets and the loop's clock.

Clients send to the proxy's port as if it were the target. Each client address is a *flow*: its
own socket towards the target (so the target sees one source per client), its own forward channel
(client to target) and backward channel (target to client), numbered in the order the clients
first spoke. Flow N's channels have the seeds `derive_seed(seed, N, "forward")` and
`derive_seed(seed, N, "backward")` (`channel.channel_pair`): the same seed and the same datagrams
in the same order give the same fates, run after run, whatever the client's port.

Each channel has at most one loop timer (`loop.call_at`), set to its `get_timer()`; a datagram
due at once (no delay) is sent from within the callback that received it. Nothing polls.

Bounds: at most `max_flows` flows (datagrams from further clients are refused and counted); a flow
that has carried nothing for `idle_timeout` seconds, and holds nothing, is forgotten (its counts
stay in the totals); each channel holds at most `limit` datagrams. `close()` sends what the
channels hold at once (or, with `flush=False`, counts it discarded), so no datagram that reached
the proxy before the close goes missing without a count.
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Callable
from dataclasses import dataclass
from types import TracebackType

from rcmlconf.impair.channel import DEFAULT_LIMIT, Counts, ImpairedChannel, channel_pair
from rcmlconf.impair.spec import Impairment
from rcmlconf.reference.timers import LoopTimer

__all__ = [
    "DEFAULT_IDLE_TIMEOUT",
    "DEFAULT_MAX_FLOWS",
    "FlowCounts",
    "ImpairProxy",
    "ProxyCounts",
]

log = logging.getLogger("rcmlconf.impair")

Address = tuple[str, int]

#: Flows at most, by default.
DEFAULT_MAX_FLOWS = 1024
#: A flow silent this long (seconds) is forgotten, by default.
DEFAULT_IDLE_TIMEOUT = 60.0
#: How long close() waits for the sockets to be closed.
CLOSE_WAIT = 2.0


@dataclass(frozen=True, slots=True)
class FlowCounts:
    """One flow's channels: `forward` from the client to the target, `backward` the other way."""

    number: int
    client: Address
    forward: Counts
    backward: Counts


@dataclass(frozen=True, slots=True)
class ProxyCounts:
    """Every flow's channels summed, forgotten flows included, and the proxy's own events."""

    forward: Counts
    backward: Counts
    #: Flows opened, and forgotten after `idle_timeout`.
    flows: int
    expired: int
    #: Datagrams from new clients while `max_flows` flows were open.
    refused: int
    #: Datagrams that arrived while the proxy was closing, not forwarded.
    late: int
    #: Datagrams a channel delivered that no socket took: its socket could not be opened, was
    #: closed, or had asked for a pause (its kernel buffer full and asyncio's past its high-water
    #: mark) rather than be given more to queue without end.
    unsent: int
    #: Errors the sockets reported (an ICMP port unreachable from the target, for one).
    errors: int


class _Direction:
    """One channel, its loop timer, and where its due datagrams go."""

    __slots__ = ("_at", "_handle", "_loop", "_output", "channel")

    def __init__(
        self,
        loop: asyncio.AbstractEventLoop,
        channel: ImpairedChannel,
        output: Callable[[bytes], None],
    ) -> None:
        self._loop = loop
        self.channel = channel
        self._output = output
        self._handle: asyncio.TimerHandle | None = None
        self._at = 0.0

    def send(self, datagram: bytes) -> None:
        now = self._loop.time()
        self.channel.send(datagram, now)
        self._deliver(now)

    def _deliver(self, now: float) -> None:
        for datagram in self.channel.due(now):
            self._output(datagram)
        at = self.channel.get_timer()
        if at is None:
            self.cancel()
        elif self._handle is None or at < self._at:
            # A handle due earlier than `at` is kept: it fires, finds nothing due, and re-arms.
            self.cancel()
            self._at = at
            self._handle = self._loop.call_at(at, self._fire, at)

    def _fire(self, at: float) -> None:
        self._handle = None
        # The loop may run a handle up to its clock resolution early: the handle's time is now.
        self._deliver(max(self._loop.time(), at))

    def cancel(self) -> None:
        if self._handle is not None:
            self._handle.cancel()
            self._handle = None

    def close(self, flush: bool) -> None:
        self.cancel()
        if flush:
            for datagram in self.channel.flush():
                self._output(datagram)
        else:
            self.channel.discard()


class _Flow:
    __slots__ = (
        "backward",
        "client",
        "closed",
        "forward",
        "idle",
        "number",
        "opening",
        "paused",
        "pending",
        "proxy",
        "transport",
    )

    def __init__(self, proxy: ImpairProxy, number: int, client: Address) -> None:
        loop = proxy.loop
        self.proxy = proxy
        self.number = number
        self.client = client
        forward, backward = channel_pair(proxy.impairment, proxy.seed, number, limit=proxy.limit)
        self.forward = _Direction(loop, forward, self._to_target)
        self.backward = _Direction(loop, backward, self._to_client)
        self.transport: asyncio.DatagramTransport | None = None
        #: Datagrams due for the target before its socket was open.
        self.pending: list[bytes] = []
        self.closed: asyncio.Future[None] = loop.create_future()
        self.idle = LoopTimer(loop, self._idle_fired)
        self.opening: asyncio.Task[None] | None = None
        self.paused = False

    def counts(self) -> FlowCounts:
        return FlowCounts(
            self.number,
            self.client,
            self.forward.channel.counts.copy(),
            self.backward.channel.counts.copy(),
        )

    def touch(self) -> None:
        self.idle.set(self.proxy.loop.time() + self.proxy.idle_timeout)

    def holds(self) -> bool:
        return bool(self.forward.channel.held or self.backward.channel.held or self.pending)

    def _to_target(self, datagram: bytes) -> None:
        transport = self.transport
        if transport is None:
            if self.opening is not None and len(self.pending) < self.proxy.limit:
                self.pending.append(datagram)
            else:
                self.proxy.unsent += 1
        elif self.paused or transport.is_closing():
            self.proxy.unsent += 1
        else:
            transport.sendto(datagram)

    def _to_client(self, datagram: bytes) -> None:
        self.proxy.send_to_client(datagram, self.client)

    def opened(self, transport: asyncio.DatagramTransport) -> None:
        self.transport = transport
        pending, self.pending = self.pending, []
        for datagram in pending:
            self._to_target(datagram)

    def _idle_fired(self) -> None:
        if self.holds():
            self.touch()
        else:
            self.proxy.forget(self, expired=True)

    def close(self, flush: bool) -> None:
        """Stop the timers, deliver (or discard) what is held, and close the socket."""
        self.idle.set(None)
        self.forward.close(flush)
        self.backward.close(flush)
        self.proxy.unsent += len(self.pending)
        self.pending = []
        if self.opening is not None and not self.opening.done():
            self.opening.cancel()
        if self.transport is not None:
            self.transport.close()
        elif not self.closed.done():
            self.closed.set_result(None)


class _Upstream(asyncio.DatagramProtocol):
    """A flow's socket towards the target."""

    def __init__(self, flow: _Flow) -> None:
        self.flow = flow

    def datagram_received(self, data: bytes, addr: Address) -> None:
        flow = self.flow
        if flow.proxy.closing:
            flow.proxy.late += 1
            return
        flow.touch()
        flow.backward.send(data)

    def error_received(self, exc: Exception) -> None:
        self.flow.proxy.errors += 1
        log.debug("flow %d to the target: %s", self.flow.number, exc)

    def pause_writing(self) -> None:
        self.flow.paused = True

    def resume_writing(self) -> None:
        self.flow.paused = False

    def connection_lost(self, exc: Exception | None) -> None:
        if not self.flow.closed.done():
            self.flow.closed.set_result(None)


class _Listener(asyncio.DatagramProtocol):
    """The proxy's own socket, which the clients send to."""

    def __init__(self, proxy: ImpairProxy) -> None:
        self.proxy = proxy
        self.closed: asyncio.Future[None] = proxy.loop.create_future()

    def datagram_received(self, data: bytes, addr: Address) -> None:
        self.proxy.from_client(data, (addr[0], addr[1]))

    def error_received(self, exc: Exception) -> None:
        self.proxy.errors += 1
        log.debug("listening socket: %s", exc)

    def pause_writing(self) -> None:
        self.proxy.paused = True

    def resume_writing(self) -> None:
        self.proxy.paused = False

    def connection_lost(self, exc: Exception | None) -> None:
        if not self.closed.done():
            self.closed.set_result(None)


class ImpairProxy:
    """A UDP proxy to `target` that impairs every flow through it (module docstring).

    ::

        async with ImpairProxy(("127.0.0.1", 7330), parse_impairment("loss=5%"), seed=1) as proxy:
            ...  # send to proxy.address instead of the target
        print(proxy.counts)
    """

    def __init__(
        self,
        target: Address,
        impairment: Impairment,
        seed: int,
        listen: Address = ("127.0.0.1", 0),
        *,
        max_flows: int = DEFAULT_MAX_FLOWS,
        idle_timeout: float = DEFAULT_IDLE_TIMEOUT,
        limit: int = DEFAULT_LIMIT,
    ) -> None:
        if max_flows < 1:
            raise ValueError(f"max_flows must be at least 1, not {max_flows}")
        if not idle_timeout > 0:
            raise ValueError(f"idle_timeout must be positive, not {idle_timeout}")
        self.target = target
        self.impairment = impairment
        self.seed = seed
        self.listen = listen
        self.max_flows = max_flows
        self.idle_timeout = idle_timeout
        self.limit = limit
        self.closing = False
        #: The listening socket asked for a pause in sending.
        self.paused = False
        self.refused = self.late = self.unsent = self.errors = 0
        #: The open flows, by client address.
        self.flows: dict[Address, _Flow] = {}
        self._next_flow = 0
        self._expired = 0
        #: The forgotten flows' counts.
        self._past_forward = Counts()
        self._past_backward = Counts()
        self._loop: asyncio.AbstractEventLoop | None = None
        self._transport: asyncio.DatagramTransport | None = None
        self._listener: _Listener | None = None
        self._closed_flows: list[asyncio.Future[None]] = []

    @property
    def loop(self) -> asyncio.AbstractEventLoop:
        if self._loop is None:
            raise RuntimeError("the proxy is not started")
        return self._loop

    @property
    def address(self) -> Address:
        """Where clients send: the listening socket's address."""
        if self._transport is None:
            raise RuntimeError("the proxy is not started")
        host, port = self._transport.get_extra_info("sockname")[:2]
        return (host, port)

    async def start(self) -> None:
        if self._loop is not None:
            raise RuntimeError("the proxy is already started")
        self._loop = asyncio.get_running_loop()
        transport, listener = await self._loop.create_datagram_endpoint(
            lambda: _Listener(self), local_addr=self.listen
        )
        self._transport, self._listener = transport, listener

    async def close(self, *, flush: bool = True) -> None:
        """Stop: what the channels hold is sent at once (`flush`) or counted discarded; then
        every socket is closed. Datagrams that arrive meanwhile are counted `late`."""
        if self.closing or self._loop is None:
            return
        self.closing = True
        opening = [flow.opening for flow in self.flows.values() if flow.opening is not None]
        if opening:  # so that what the forward channels flush has a socket to go to
            await asyncio.wait(opening, timeout=CLOSE_WAIT)
        for flow in list(self.flows.values()):
            self.forget(flow, flush=flush)
        waits: list[asyncio.Future[None]] = list(self._closed_flows)
        if self._transport is not None and self._listener is not None:
            self._transport.close()
            waits.append(self._listener.closed)
        if waits:
            await asyncio.wait(waits, timeout=CLOSE_WAIT)

    async def __aenter__(self) -> ImpairProxy:
        await self.start()
        return self

    async def __aexit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        await self.close()

    @property
    def counts(self) -> ProxyCounts:
        """Every flow's counts summed, the forgotten flows' included, and the proxy's own."""
        forward, backward = self._past_forward.copy(), self._past_backward.copy()
        for flow in self.flows.values():
            forward += flow.forward.channel.counts
            backward += flow.backward.channel.counts
        return ProxyCounts(
            forward,
            backward,
            flows=self._next_flow,
            expired=self._expired,
            refused=self.refused,
            late=self.late,
            unsent=self.unsent,
            errors=self.errors,
        )

    def flow_counts(self) -> list[FlowCounts]:
        """Each open flow's counts, in the order the flows were opened."""
        return [flow.counts() for flow in self.flows.values()]

    # The protocols' side.

    def from_client(self, data: bytes, client: Address) -> None:
        if self.closing:
            self.late += 1
            return
        flow = self.flows.get(client)
        if flow is None:
            if len(self.flows) >= self.max_flows:
                self.refused += 1
                return
            flow = self._open(client)
        flow.touch()
        flow.forward.send(data)

    def send_to_client(self, datagram: bytes, client: Address) -> None:
        transport = self._transport
        if transport is None or self.paused or transport.is_closing():
            self.unsent += 1
        else:
            transport.sendto(datagram, client)

    def forget(self, flow: _Flow, *, flush: bool = False, expired: bool = False) -> None:
        """Close a flow and keep its counts in the totals."""
        if self.flows.get(flow.client) is not flow:
            return
        flow.close(flush)
        del self.flows[flow.client]
        self._past_forward += flow.forward.channel.counts
        self._past_backward += flow.backward.channel.counts
        if expired:
            self._expired += 1
        if not flow.closed.done():
            self._closed_flows.append(flow.closed)
        self._closed_flows = [f for f in self._closed_flows if not f.done()]

    def _open(self, client: Address) -> _Flow:
        flow = _Flow(self, self._next_flow, client)
        self._next_flow += 1
        self.flows[client] = flow
        flow.opening = self.loop.create_task(self._connect(flow))
        return flow

    async def _connect(self, flow: _Flow) -> None:
        try:
            transport, _ = await self.loop.create_datagram_endpoint(
                lambda: _Upstream(flow), remote_addr=self.target
            )
        except OSError as exc:
            log.warning("flow %d: cannot open a socket to %s: %s", flow.number, self.target, exc)
            self.errors += 1
            flow.opening = None
            self.forget(flow)
            return
        if self.flows.get(flow.client) is not flow:  # forgotten while it opened
            transport.close()
            return
        flow.opening = None
        flow.opened(transport)
