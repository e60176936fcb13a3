"""The reference server on loopback for a test, and a raw control connection to talk to it."""

from __future__ import annotations

import asyncio
import functools
from collections.abc import AsyncIterator, Callable, Coroutine, Sequence
from contextlib import asynccontextmanager
from pathlib import Path
from typing import Any

from rcmlconf.rctp.messages import Request, Response
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


class RawSession:
    """A raw connection with a session open, numbering its requests."""

    def __init__(self, raw: Raw, session: str) -> None:
        self.raw, self.session, self.cseq = raw, session, 1

    @classmethod
    async def open(cls, server: ReferenceServer) -> RawSession:
        raw = await Raw.open(server)
        await raw.send(b"CONNECT / RCTP/2.0\r\nCSeq: 1\r\n\r\n")
        answer = await raw.response()
        assert answer.status == 200, answer
        return cls(raw, (answer.headers.get("Session") or "").split(";")[0])

    async def send(
        self, method: str, target: str, headers: Sequence[tuple[str, str]] = (), body: bytes = b""
    ) -> None:
        """A request with the next CSeq and the session, as written; no waiting."""
        self.cseq += 1
        fields = [("CSeq", str(self.cseq)), ("Session", self.session), *headers]
        if body:
            fields.append(("Content-Length", str(len(body))))
        head = f"{method} {target} RCTP/2.0\r\n"
        head += "".join(f"{name}: {value}\r\n" for name, value in fields)
        await self.raw.send(head.encode() + b"\r\n" + body)

    async def ask(
        self, method: str, target: str, headers: Sequence[tuple[str, str]] = (), body: bytes = b""
    ) -> Response:
        await self.send(method, target, headers, body)
        return await self.raw.response()

    async def answer(self, request: Request, status: int = 200, reason: str = "OK") -> None:
        """Answer one of the server's requests."""
        fields = f"CSeq: {request.headers.get('CSeq')}\r\nSession: {self.session}\r\n"
        await self.raw.send(f"RCTP/2.0 {status} {reason}\r\n{fields}\r\n".encode())

    async def request(self, timeout: float = 5.0) -> Request | None:
        """The server's next request; None when none comes within `timeout`."""
        try:
            message = await self.raw.message(timeout)
        except TimeoutError:
            return None
        assert isinstance(message, Request), message
        return message

    def close(self) -> None:
        self.raw.close()
