"""A full table of connections makes room for a new one (D-RCTP-32, R-RCTP-67): it closes the
oldest connection without a session of the address that holds the most of them, so that a peer
flooding the table with idle connections loses its own, never a newcomer's; a connection with a
session is never closed to make room."""

from __future__ import annotations

import asyncio
import random
import socket
from collections import Counter

from support.servers import Raw, RawSession, run, serving
from support.waits import until

from rcmlconf.reference.server.adapter import ReferenceServer
from rcmlconf.reference.server.limits import PeerCount, ServerLimits

#: A small table: 20 connections in all.
TABLE = 20
#: The flooding addresses and how many idle connections each holds: 127.0.0.2 the most.
FLOOD = {"127.0.0.2": 8, "127.0.0.3": 3, "127.0.0.4": 3, "127.0.0.5": 3, "127.0.0.6": 3}
NEWCOMER = "127.0.0.7"
CONNECT = b"CONNECT / RCTP/2.0\r\nCSeq: 1\r\n\r\n"


async def _from(server: ReferenceServer, source: str) -> Raw:
    """A control connection from another loopback address (all of 127/8 is loopback on Linux):
    another peer."""
    reader, writer = await asyncio.open_connection("127.0.0.1", server.port, local_addr=(source, 0))
    return Raw(reader, writer)


async def _session_from(server: ReferenceServer, source: str) -> RawSession:
    raw = await _from(server, source)
    await raw.send(CONNECT)
    answer = await raw.response()
    assert answer.status == 200, answer
    return RawSession(raw, (answer.headers.get("Session") or "").split(";")[0])


def _gone(raw: Raw) -> bool:
    """Whether the server has closed or reset the connection, as the kernel has it now (a peek
    at a second descriptor of the socket, nothing read): on loopback a close arrives as the
    server makes it, before the answers the server writes after it."""
    if raw.reader.at_eof() or raw.reader.exception() is not None or raw.writer.is_closing():
        return True
    fd = raw.writer.get_extra_info("socket").fileno()
    with socket.fromfd(fd, socket.AF_INET, socket.SOCK_STREAM) as same:
        try:
            return same.recv(1, socket.MSG_PEEK | socket.MSG_DONTWAIT) == b""
        except BlockingIOError:
            return False
        except ConnectionResetError:
            return True


def _closed(raws: list[Raw]) -> list[Raw]:
    return [raw for raw in raws if _gone(raw)]


@run
async def test_a_newcomer_to_a_full_table_of_idle_connections_is_served() -> None:
    async with serving(limits=ServerLimits(connections=TABLE)) as server:
        idle = {
            source: [await _from(server, source) for _ in range(n)] for source, n in FLOOD.items()
        }
        everyone = [raw for raws in idle.values() for raw in raws]
        assert await until(lambda: server.connections.total == TABLE)

        newcomer = await _session_from(server, NEWCOMER)
        assert (await newcomer.ask("READ", "/head/control/led")).status == 200
        # The oldest idle connection of the address with the most was closed, none other.
        assert _closed(everyone) == [idle["127.0.0.2"][0]]
        assert server.connections.evicted == 1

        # The flood opens a connection again: it makes room with its own next oldest, and the
        # newcomer, a session now, keeps its place.
        again = await _from(server, "127.0.0.2")
        assert (await newcomer.ask("READ", "/head/control/led")).status == 200
        assert _closed(everyone) == idle["127.0.0.2"][:2]
        assert not _gone(again)
        for raw in (*everyone, again, newcomer.raw):
            raw.close()


@run
async def test_connections_with_a_session_are_never_closed_to_make_room() -> None:
    """A table of 19 sessions, all of one address, and one idle connection of another: a
    newcomer closes the idle one (sessions do not count toward an address's most), then the
    table holds sessions only and the next newcomer is closed at once, every session kept."""
    async with serving(limits=ServerLimits(connections=TABLE)) as server:
        sessions = [await _session_from(server, "127.0.0.2") for _ in range(TABLE - 1)]
        idle = await _from(server, "127.0.0.3")
        assert await until(lambda: server.connections.total == TABLE)

        newcomer = await _session_from(server, NEWCOMER)
        assert (await newcomer.ask("READ", "/head/control/led")).status == 200
        assert _gone(idle)

        beyond = await _from(server, "127.0.0.4")
        assert await until(lambda: _gone(beyond))
        for session in (*sessions, newcomer):
            assert (await session.ask("READ", "/head/control/led")).status == 200
            assert not _gone(session.raw)
        assert server.connections.evicted == 1
        for raw in (idle, beyond, *(s.raw for s in (*sessions, newcomer))):
            raw.close()


class _Connection:
    """A connection of the table's model: told when it is closed to make room."""

    def __init__(self, peer: str, closed: list[_Connection]) -> None:
        self.peer, self.closed = peer, closed

    def evict(self) -> None:
        self.closed.append(self)


def test_the_table_closes_the_oldest_idle_connection_of_an_address_holding_the_most() -> None:
    """PeerCount's buckets against a plain model: 3,000 random opens, sessions and leaves over
    seven addresses, each eviction checked against every address's count by hand."""
    rng = random.Random(0)
    closed: list[_Connection] = []
    table = PeerCount(cap=40, per_peer=12)
    opened: list[_Connection] = []  # oldest first, as admitted
    kept: set[_Connection] = set()  # with a session, or closed to make room
    for _ in range(3000):
        action = rng.random()
        if action < 0.6 or not opened:
            peer = f"127.0.0.{rng.randrange(2, 9)}"
            idle = [c for c in opened if c not in kept]
            counts = Counter(c.peer for c in idle)
            full = len(opened) >= table.cap
            beyond = sum(1 for c in opened if c.peer == peer) >= table.per_peer
            new = _Connection(peer, closed)
            before = len(closed)
            admitted = table.admit(peer, new, 0.0)
            assert admitted is not (beyond or (full and not idle))
            if admitted and full:
                (evicted,) = closed[before:]
                assert counts[evicted.peer] == max(counts.values())
                assert evicted is next(c for c in idle if c.peer == evicted.peer)
                kept.add(evicted)
            else:
                assert len(closed) == before
            if admitted:
                opened.append(new)
        elif action < 0.75:
            candidate = rng.choice(opened)
            if candidate not in kept:
                table.seated(candidate.peer, candidate)
                kept.add(candidate)
        else:
            leaving = rng.choice(opened)
            table.leave(leaving.peer, leaving)
            opened.remove(leaving)
            kept.discard(leaving)
        assert table.total == len(opened)
    assert table.evicted == len(closed) > 100
