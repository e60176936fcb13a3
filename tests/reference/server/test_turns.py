"""The connections' work in turns of the loop (`turns.Turns`, D-RCTP-32), on a real loop with a
real socket on 127.0.0.1 for a connection that becomes ready."""

from __future__ import annotations

import asyncio
import socket
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager

from support.servers import run
from support.waits import until

from rcmlconf.reference.server.turns import Turns


@contextmanager
def _ready_socket(readable: Callable[[], None]) -> Iterator[socket.socket]:
    """A connection on 127.0.0.1 whose server side, once readable, calls `readable` from the
    loop as the server's connections do; the client side, to send a byte with."""
    loop = asyncio.get_running_loop()
    with socket.create_server(("127.0.0.1", 0)) as listener:
        client = socket.create_connection(listener.getsockname()[:2], timeout=5.0)
        connection, _ = listener.accept()
        with client, connection:
            connection.setblocking(False)

            def ready() -> None:
                connection.recv(1)
                loop.remove_reader(connection)
                readable()

            loop.add_reader(connection, ready)
            try:
                yield client
            finally:
                loop.remove_reader(connection)


@run
async def test_a_request_that_comes_while_others_wait_is_done_before_their_queues() -> None:
    """D-RCTP-32: the queues are served after the sockets ready in a turn: work whose peer waits
    for nothing is done in the turn that reads it, the turn's budget whole. (Served at the head
    of the turn, the queued work took the budget first and the request waited its turn.) A
    budget of a microsecond: a turn does one piece of work at once, or none."""
    loop = asyncio.get_running_loop()
    turns = Turns(loop, budget=1e-6, share=1e-6)
    done: list[str] = []
    for index in range(3):
        turns.later("127.0.0.2", lambda index=index: done.append(f"queued {index}"))
    at_once: list[bool] = []

    def readable() -> None:
        at_once.append(turns.run("127.0.0.1", lambda: done.append("request")))

    with _ready_socket(readable) as client:
        client.sendall(b"R")  # ready in the loop's next turn, as the queues are
        assert await until(lambda: len(done) == 4)
    assert at_once == [True]
    assert done == ["request", "queued 0", "queued 1", "queued 2"]


@run
async def test_a_peer_ahead_of_those_that_wait_waits_its_turn_within_the_budget() -> None:
    """D-RCTP-32: while others wait, a peer that has had more time than they is not done at
    once, though the turn's budget has room: it waits its turn, after theirs; a peer that has
    had none is done at once. (Done at once up to its share, each attacking address took the
    budget before a legitimate request of the same turn.) A budget of a microsecond, so that the
    queues move a piece a turn, and a share of a second: neither is the reason here."""
    loop = asyncio.get_running_loop()
    turns = Turns(loop, budget=1e-6, share=1.0)
    done: list[str] = []
    at_once: list[bool] = []

    def readable() -> None:
        at_once.append(turns.run("127.0.0.2", lambda: done.append("127.0.0.2 1")))
        at_once.append(turns.run("127.0.0.1", lambda: done.append("127.0.0.1")))

    with _ready_socket(readable) as client:

        def first() -> None:  # served first: its peer is then ahead of the other's
            done.append("127.0.0.2 0")
            client.sendall(b"R")  # ready in the next turn, before its queues

        turns.later("127.0.0.2", first)
        turns.later("127.0.0.3", lambda: done.append("127.0.0.3"))
        assert await until(lambda: len(done) == 4)
    assert at_once == [False, True]
    assert done == ["127.0.0.2 0", "127.0.0.1", "127.0.0.3", "127.0.0.2 1"]


@run
async def test_a_piece_is_charged_the_cpu_time_it_took_not_the_wall_time() -> None:
    """The queues are shared by the CPU time their work took: a piece during which the server
    did not run (here it sleeps 50 ms; on a busy machine, another process runs) is not charged
    the wait, and its peer's next piece comes after one of a peer that burns 1 ms of CPU a
    piece, not after fifty."""
    loop = asyncio.get_running_loop()
    turns = Turns(loop, budget=1e-6, share=1e-6)
    done: list[str] = []

    def asleep() -> None:
        time.sleep(0.05)
        done.append("127.0.0.2 asleep")

    def burn(index: int) -> None:
        until_cpu = time.thread_time() + 0.001
        while time.thread_time() < until_cpu:
            pass
        done.append(f"127.0.0.3 {index}")

    turns.later("127.0.0.2", asleep)
    for index in range(5):
        turns.later("127.0.0.3", lambda index=index: burn(index))
    turns.later("127.0.0.2", lambda: done.append("127.0.0.2 next"))
    assert await until(lambda: turns.waiting == 0)
    assert done[:3] == ["127.0.0.2 asleep", "127.0.0.3 0", "127.0.0.2 next"]


@run
async def test_work_done_while_no_one_waits_is_no_debt_later() -> None:
    """D-RCTP-32: a peer's work done at once while no one waited (a quiet while's requests) is
    no debt of its peer: once another peer's burst waits, the peer's next piece is served after
    a piece of the burst, not after as much time as it had. (Counted, a legitimate client's
    quiet minute made its READ wait until a flood had had as much: 240 ms in
    bench/hostile_load.py --turns.) Each piece burns 0.2 ms of CPU; a budget and a share of a
    microsecond: a turn does one piece at once, or none."""
    loop = asyncio.get_running_loop()
    turns = Turns(loop, budget=1e-6, share=1e-6)
    done: list[str] = []

    def burn(label: str) -> None:
        until_cpu = time.thread_time() + 0.0002
        while time.thread_time() < until_cpu:
            pass
        done.append(label)

    at_once: list[bool] = []
    for index in range(50):  # the quiet while: 10 ms of CPU, each piece in a turn of its own
        at_once.append(turns.run("127.0.0.1", lambda index=index: burn(f"quiet {index}")))
        await asyncio.sleep(0)
    assert await until(lambda: turns.waiting == 0)
    done.clear()
    for index in range(100):  # the burst: 20 ms of CPU
        turns.later("127.0.0.2", lambda index=index: burn(f"burst {index}"))
    turns.later("127.0.0.1", lambda: burn("quiet again"))
    assert await until(lambda: turns.waiting == 0)
    assert done.index("quiet again") <= 2, done[:60]
    assert all(at_once)
