"""The connections' work in turns of the loop (`turns.Turns`, D-RCTP-32), on a real loop with a
real socket on 127.0.0.1 for a connection that becomes ready."""

from __future__ import annotations

import asyncio
import socket

from support.servers import run
from support.waits import until

from rcmlconf.reference.server.turns import Turns


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
    with socket.create_server(("127.0.0.1", 0)) as listener:
        client = socket.create_connection(listener.getsockname()[:2], timeout=5.0)
        connection, _ = listener.accept()
        with client, connection:
            connection.setblocking(False)

            def readable() -> None:
                connection.recv(1)
                loop.remove_reader(connection)
                at_once.append(turns.run("127.0.0.1", lambda: done.append("request")))

            loop.add_reader(connection, readable)
            client.sendall(b"R")  # ready in the loop's next turn, as the queues are
            assert await until(lambda: len(done) == 4)
    assert at_once == [True]
    assert done == ["request", "queued 0", "queued 1", "queued 2"]
