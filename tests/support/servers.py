"""The reference server on loopback for a test, and a raw control connection to talk to it."""

from __future__ import annotations

import asyncio
import functools
from collections.abc import AsyncIterator, Callable, Coroutine
from contextlib import asynccontextmanager
from pathlib import Path
from typing import Any

from rcmlconf.rctp.messages import Response
from rcmlconf.rctp.reader import MessageReader
from rcmlconf.reference.drivers import choose_driver
from rcmlconf.reference.server.adapter import ReferenceServer, ServerSettings
from support.robots import TESTBOT, robot

#: No test runs longer than this, whatever hangs.
TEST_BOUND = 30.0


def run(test: Callable[..., Coroutine[Any, Any, None]]) -> Callable[..., None]:
    """Run an async test in its own loop, bounded in time."""

    @functools.wraps(test)
    def wrapper(*args: Any, **kwargs: Any) -> None:
        asyncio.run(asyncio.wait_for(test(*args, **kwargs), TEST_BOUND))

    return wrapper


@asynccontextmanager
async def serving(rcml: Path = TESTBOT, **settings: Any) -> AsyncIterator[ReferenceServer]:
    """The reference server of `rcml` with its default driver, on free loopback ports."""
    model = robot(rcml)
    options = {"port": 0, "http_port": 0, **settings}
    server = ReferenceServer(rcml, model, choose_driver("auto", model), ServerSettings(**options))
    await server.start()
    try:
        yield server
    finally:
        await server.stop()


class Raw:
    """A control connection that sends bytes as given and reads whole messages back."""

    def __init__(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        self.reader, self.writer = reader, writer
        self.messages = MessageReader()

    @classmethod
    async def open(cls, server: ReferenceServer) -> Raw:
        return cls(*await asyncio.open_connection("127.0.0.1", server.port))

    async def send(self, data: bytes) -> None:
        self.writer.write(data)
        await self.writer.drain()

    async def message(self, timeout: float = 5.0) -> Any:
        """The next whole message; None when the server closed the connection."""
        while (message := self.messages.next_message()) is None:
            data = await asyncio.wait_for(self.reader.read(65536), timeout)
            if not data:
                return None
            self.messages.feed(data)
        return message

    async def response(self, timeout: float = 5.0) -> Response:
        message = await self.message(timeout)
        assert isinstance(message, Response), message
        return message

    async def closed(self, timeout: float = 5.0) -> bool:
        """Whether the server closes the connection (after anything still on its way)."""
        try:
            while await asyncio.wait_for(self.reader.read(65536), timeout):
                pass
        except TimeoutError:
            return False
        return True

    def close(self) -> None:
        self.writer.close()
