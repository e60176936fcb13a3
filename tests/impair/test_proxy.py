"""The impairing proxy over real loopback sockets, between a client and a UDP echo target.

No assertion depends on how fast the machine is: order and counts, and lower bounds on round
trips that the channels' own schedule guarantees. Every wait is bounded.
"""

from __future__ import annotations

import asyncio
import functools
from collections.abc import AsyncIterator, Callable, Coroutine
from contextlib import asynccontextmanager
from typing import Any, cast

from rcmlconf.impair.channel import channel_pair
from rcmlconf.impair.proxy import ImpairProxy
from rcmlconf.impair.spec import Impairment, parse_impairment

HOST = "127.0.0.1"
#: No test runs longer than this, whatever hangs.
BOUND = 10.0
Address = tuple[str, int]


def run(test: Callable[[], Coroutine[Any, Any, None]]) -> Callable[[], None]:
    @functools.wraps(test)
    def wrapper() -> None:
        asyncio.run(asyncio.wait_for(test(), BOUND))

    return wrapper


async def until(condition: Callable[[], bool], timeout: float = 5.0) -> None:
    async def poll() -> None:
        while not condition():
            await asyncio.sleep(0.002)

    await asyncio.wait_for(poll(), timeout)


class Echo(asyncio.DatagramProtocol):
    """The target: sends every datagram back to where it came from."""

    def __init__(self) -> None:
        self.received: list[tuple[bytes, Address]] = []
        self.transport: asyncio.DatagramTransport | None = None

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        # (not an instance of DatagramTransport before Python 3.12)
        self.transport = cast(asyncio.DatagramTransport, transport)

    def datagram_received(self, data: bytes, addr: Address) -> None:
        self.received.append((data, addr))
        assert self.transport is not None
        self.transport.sendto(data, addr)


class Client(asyncio.DatagramProtocol):
    def __init__(self) -> None:
        self.received: list[tuple[bytes, float]] = []
        self.transport: asyncio.DatagramTransport | None = None

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        # (not an instance of DatagramTransport before Python 3.12)
        self.transport = cast(asyncio.DatagramTransport, transport)

    def datagram_received(self, data: bytes, addr: Address) -> None:
        self.received.append((data, asyncio.get_running_loop().time()))

    def send(self, data: bytes) -> None:
        assert self.transport is not None
        self.transport.sendto(data)

    @property
    def address(self) -> Address:
        assert self.transport is not None
        host, port = self.transport.get_extra_info("sockname")[:2]
        return (host, port)

    @property
    def datagrams(self) -> list[bytes]:
        return [data for data, _ in self.received]


@asynccontextmanager
async def echo_target() -> AsyncIterator[tuple[Echo, Address]]:
    loop = asyncio.get_running_loop()
    transport, echo = await loop.create_datagram_endpoint(Echo, local_addr=(HOST, 0))
    try:
        yield echo, transport.get_extra_info("sockname")[:2]
    finally:
        transport.close()


@asynccontextmanager
async def client(to: Address) -> AsyncIterator[Client]:
    loop = asyncio.get_running_loop()
    transport, protocol = await loop.create_datagram_endpoint(Client, remote_addr=to)
    try:
        yield protocol
    finally:
        transport.close()


@asynccontextmanager
async def proxied(
    spec: str, seed: int = 1, **options: Any
) -> AsyncIterator[tuple[Echo, ImpairProxy]]:
    async with echo_target() as (echo, target):
        proxy = ImpairProxy(target, parse_impairment(spec), seed, **options)
        await proxy.start()
        try:
            yield echo, proxy
        finally:
            await proxy.close()


def datagram(i: int) -> bytes:
    return b"#%05d" % i


def echoed(c: Client, n: int) -> bool:
    return len(c.received) >= n


@run
async def test_no_impairment_echoes_everything_in_order() -> None:
    async with proxied("none") as (echo, proxy), client(proxy.address) as c:
        assert proxy.address[0] == HOST
        for batch in range(10):
            for i in range(batch * 20, batch * 20 + 20):
                c.send(datagram(i))
            await until(functools.partial(echoed, c, batch * 20 + 20))
        assert c.datagrams == [datagram(i) for i in range(200)]
        assert [data for data, _ in echo.received] == c.datagrams
        # The target sees the proxy's socket for this client, not the client.
        sources = {addr for _, addr in echo.received}
        assert len(sources) == 1
        assert sources != {c.address}
        counts = proxy.counts
        assert counts.forward.sent == counts.forward.delivered == 200
        assert counts.backward.sent == counts.backward.delivered == 200
        assert (counts.flows, counts.refused, counts.unsent, counts.errors) == (1, 0, 0, 0)


@run
async def test_total_loss_forwards_nothing() -> None:
    async with proxied("loss=100%") as (echo, proxy), client(proxy.address) as c:
        for i in range(20):
            c.send(datagram(i))
        await until(lambda: proxy.counts.forward.sent == 20)
        counts = proxy.counts
        assert counts.forward.lost == 20
        assert counts.forward.delivered == 0
        assert counts.backward.sent == 0
        assert echo.received == []
        assert c.received == []


@run
async def test_a_delay_each_way_makes_the_round_trip_at_least_twice_as_long() -> None:
    async with proxied("delay=50ms") as (_, proxy), client(proxy.address) as c:
        loop = asyncio.get_running_loop()
        sent_at = []
        for i in range(5):
            sent_at.append(loop.time())
            c.send(datagram(i))
            await asyncio.sleep(0.005)
        await until(lambda: len(c.received) == 5)
        assert c.datagrams == [datagram(i) for i in range(5)]
        for start, (_, arrived) in zip(sent_at, c.received, strict=True):
            # The channels hold each datagram 50 ms each way, counted from after it was sent.
            assert arrived - start >= 0.100 - 0.001
        assert proxy.counts.forward.delivered == proxy.counts.backward.delivered == 5


@run
async def test_each_client_is_its_own_flow_with_its_own_source() -> None:
    async with (
        proxied("delay=1ms") as (echo, proxy),
        client(proxy.address) as a,
        client(proxy.address) as b,
    ):
        for i in range(10):
            a.send(b"a" + datagram(i))
            b.send(b"b" + datagram(i))
        await until(lambda: len(a.received) == 10 and len(b.received) == 10)
        assert a.datagrams == [b"a" + datagram(i) for i in range(10)]
        assert b.datagrams == [b"b" + datagram(i) for i in range(10)]
        assert len({addr for _, addr in echo.received}) == 2
        flows = proxy.flow_counts()
        assert [flow.number for flow in flows] == [0, 1]
        assert {flow.client for flow in flows} == {a.address, b.address}
        assert all(flow.forward.sent == flow.backward.delivered == 10 for flow in flows)
        assert proxy.counts.forward.sent == 20


async def echoed_through(spec: str, seed: int, n: int) -> list[bytes]:
    """What a client gets back of `n` datagrams, sent in batches so that none queues long."""
    async with proxied(spec, seed) as (_, proxy), client(proxy.address) as c:
        for batch in range(0, n, 10):
            for i in range(batch, min(batch + 10, n)):
                c.send(datagram(i))

            def settled(sent: int = min(batch + 10, n)) -> bool:
                counts = proxy.counts
                return (
                    counts.forward.sent == sent
                    and counts.backward.sent == counts.forward.delivered
                    and len(c.received) == counts.backward.delivered
                )

            await until(settled)
        return c.datagrams


@run
async def test_the_same_seed_gives_the_same_losses_as_the_channels_alone() -> None:
    spec, seed, n = "loss=30%", 5, 100
    got = await echoed_through(spec, seed, n)
    assert await echoed_through(spec, seed, n) == got
    assert await echoed_through(spec, seed + 1, n) != got
    # Flow 0's channels, simulated: the proxy adds nothing of its own.
    forward, backward = channel_pair(parse_impairment(spec), seed, 0)
    expected = []
    for i in range(n):
        forward.send(datagram(i), 0.0)
        for data in forward.due(0.0):
            backward.send(data, 0.0)
            expected.extend(backward.due(0.0))
    assert got == expected
    assert 0 < len(got) < n


@run
async def test_clients_beyond_the_flow_bound_are_refused() -> None:
    async with (
        proxied("none", max_flows=1) as (echo, proxy),
        client(proxy.address) as a,
        client(proxy.address) as b,
    ):
        a.send(b"first")
        await until(lambda: len(a.received) == 1)
        b.send(b"second")
        await until(lambda: proxy.counts.refused == 1)
        assert b.received == []
        assert [data for data, _ in echo.received] == [b"first"]


@run
async def test_an_idle_flow_is_forgotten_and_its_counts_kept() -> None:
    async with proxied("none", idle_timeout=0.05) as (_, proxy), client(proxy.address) as c:
        c.send(b"one")
        await until(lambda: len(c.received) == 1)
        await until(lambda: not proxy.flows)
        counts = proxy.counts
        assert (counts.flows, counts.expired) == (1, 1)
        assert counts.forward.sent == counts.backward.delivered == 1
        c.send(b"two")  # the same client again: a new flow
        await until(lambda: len(c.received) == 2)
        assert [flow.number for flow in proxy.flow_counts()] == [1]
        assert proxy.counts.forward.sent == 2


@run
async def test_close_sends_what_the_channels_hold() -> None:
    async with echo_target() as (echo, target):
        proxy = ImpairProxy(target, Impairment(delay=10.0), seed=1)
        await proxy.start()
        async with client(proxy.address) as c:
            for i in range(3):
                c.send(datagram(i))
            await until(lambda: proxy.counts.forward.sent == 3)
            assert echo.received == []
            await proxy.close()
            assert proxy.counts.forward.delivered == 3
            await until(lambda: len(echo.received) == 3)
            assert [data for data, _ in echo.received] == [datagram(i) for i in range(3)]
            await proxy.close()  # twice is harmless


@run
async def test_close_without_flush_counts_what_it_discards() -> None:
    async with proxied("delay=10s") as (_, proxy), client(proxy.address) as c:
        for i in range(3):
            c.send(datagram(i))
        await until(lambda: proxy.counts.forward.sent == 3)
        await proxy.close(flush=False)
        counts = proxy.counts
        assert (counts.forward.delivered, counts.forward.discarded) == (0, 3)


@run
async def test_a_target_that_is_not_there_is_counted_as_errors() -> None:
    loop = asyncio.get_running_loop()
    transport, _ = await loop.create_datagram_endpoint(
        asyncio.DatagramProtocol, local_addr=(HOST, 0)
    )
    nobody = transport.get_extra_info("sockname")[:2]
    transport.close()  # a port where nothing listens
    async with ImpairProxy(nobody, Impairment(), seed=1) as proxy, client(proxy.address) as c:

        async def keep_sending() -> None:
            while proxy.counts.errors == 0:
                c.send(b"anyone?")
                await asyncio.sleep(0.01)

        await asyncio.wait_for(keep_sending(), 5.0)
        assert c.received == []
    assert proxy.closing
