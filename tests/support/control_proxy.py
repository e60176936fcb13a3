"""A TCP proxy in front of an RCTP/2.0 server that changes what the server sends, message by
message, to make a server that behaves as another conforming server would: one that writes the
grammar's tokens in other letter cases, or one that pushes its requests later.

Messages are framed by their header block and Content-Length only (the reference server's are
well-formed); what the client sends passes as it is.
"""

from __future__ import annotations

import asyncio
import contextlib
import re
from collections import Counter
from collections.abc import Callable

Address = tuple[str, int]
_LENGTH = re.compile(rb"\r\ncontent-length:[ \t]*([0-9]+)", re.IGNORECASE)


class ControlProxy:
    """`rewrite` changes each message of the server's; a server request (a first line that is
    not a status line) is held `delay` seconds, in order, while its responses pass at once."""

    def __init__(
        self,
        upstream: Address,
        rewrite: Callable[[bytes], bytes] = lambda message: message,
        delay: float = 0.0,
    ) -> None:
        self.upstream = upstream
        self.rewrite = rewrite
        self.delay = delay
        #: Server requests held back, by method.
        self.delayed: Counter[str] = Counter()
        self._server: asyncio.Server | None = None
        self._tasks: set[asyncio.Task[None]] = set()

    async def start(self) -> Address:
        self._server = await asyncio.start_server(self._accepted, "127.0.0.1", 0)
        host, port = self._server.sockets[0].getsockname()[:2]
        return host, port

    async def close(self) -> None:
        if self._server is not None:
            self._server.close()
        for task in self._tasks:
            task.cancel()

    async def _accepted(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        try:
            up_reader, up_writer = await asyncio.open_connection(*self.upstream)
        except OSError:
            writer.close()
            return
        await asyncio.gather(self._forward(reader, up_writer), self._backward(up_reader, writer))

    async def _forward(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        with contextlib.suppress(OSError, ConnectionError):
            while data := await reader.read(65536):
                writer.write(data)
                await writer.drain()
        _close(writer)

    async def _backward(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        held: asyncio.Queue[tuple[float, bytes] | None] = asyncio.Queue()
        sender = asyncio.ensure_future(self._send_held(held, writer))
        self._tasks.add(sender)
        buffer = b""
        with contextlib.suppress(OSError, ConnectionError):
            while data := await reader.read(65536):
                buffer += data
                while (message := _frame(buffer)) is not None:
                    buffer = buffer[len(message) :]
                    out = self.rewrite(message)
                    if self.delay and not message.startswith(b"RCTP/"):
                        self.delayed[message.split(b" ", 1)[0].decode()] += 1
                        held.put_nowait((asyncio.get_running_loop().time(), out))
                    else:
                        writer.write(out)
                        await writer.drain()
        held.put_nowait(None)
        await asyncio.wait({sender})  # cancelled by close(): this connection's end, not an error
        self._tasks.discard(sender)
        _close(writer)

    async def _send_held(
        self, held: asyncio.Queue[tuple[float, bytes] | None], writer: asyncio.StreamWriter
    ) -> None:
        """The held requests, each `delay` after it came, in the order they came."""
        loop = asyncio.get_running_loop()
        while (item := await held.get()) is not None:
            came, message = item
            await asyncio.sleep(max(0.0, came + self.delay - loop.time()))
            with contextlib.suppress(OSError, ConnectionError):
                writer.write(message)
                await writer.drain()


def _frame(buffer: bytes) -> bytes | None:
    """The first whole message of `buffer`, or None while it is incomplete."""
    end = buffer.find(b"\r\n\r\n")
    if end < 0:
        return None
    found = _LENGTH.search(buffer[: end + 2])
    size = end + 4 + (int(found.group(1)) if found else 0)
    return buffer[:size] if len(buffer) >= size else None


def _close(writer: asyncio.StreamWriter) -> None:
    with contextlib.suppress(OSError, ConnectionError, RuntimeError):
        writer.close()
