"""Where RCTP/2.0 clients under test connect (`--role client --listen PORT`): the harness plays
the server, as Autobahn's fuzzing server does. Each client case takes the next connection; a
client under test is expected to connect again after each one ends. The embedded reference has
a `summon` that starts one reference client whenever a case waits for a connection."""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import Awaitable, Callable

from rcmlconf.conformance.probes.control import ControlProbe
from rcmlconf.conformance.transcript import Address, Transcript
from rcmlconf.conformance.verdicts import Inconclusive

Summon = Callable[[Address], Awaitable[None]]


class ClientListener:
    def __init__(self, summon: Summon | None = None) -> None:
        self._summon = summon
        self._accepted: asyncio.Queue[tuple[asyncio.StreamReader, asyncio.StreamWriter]]
        self._accepted = asyncio.Queue()
        self._server: asyncio.Server | None = None
        self._tasks: set[asyncio.Task[None]] = set()

    async def start(self, host: str, port: int) -> None:
        def accepted(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
            self._accepted.put_nowait((reader, writer))

        self._server = await asyncio.start_server(accepted, host, port)

    @property
    def address(self) -> Address:
        assert self._server is not None, "start() first"
        host, port = self._server.sockets[0].getsockname()[:2]
        return host, port

    async def accept(self, transcript: Transcript, wait: float) -> ControlProbe:
        """The next client's connection; inconclusive if none comes within `wait`."""
        if self._summon is not None and self._accepted.empty():
            task = asyncio.ensure_future(self._summon(self.address))
            self._tasks.add(task)
            task.add_done_callback(self._tasks.discard)
        try:
            reader, writer = await asyncio.wait_for(self._accepted.get(), wait)
        except TimeoutError:
            host, port = self.address
            raise Inconclusive(f"no client connected to {host}:{port} within {wait:g} s") from None
        probe = ControlProbe(reader, writer, transcript, wait).serving()
        peer = probe.peer
        transcript.note(f"{probe.name} a client connected from {peer[0]}:{peer[1]}")
        return probe

    async def close(self) -> None:
        for task in list(self._tasks):
            task.cancel()
        for task in list(self._tasks):
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await task
        while not self._accepted.empty():
            _, writer = self._accepted.get_nowait()
            writer.close()
        if self._server is not None:
            self._server.close()
            await self._server.wait_closed()
