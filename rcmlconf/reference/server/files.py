"""The robot's files over HTTP/1.1 (D-RCTP-29; paper Fig. 5: the browser downloads the RCML and
RXID files "with a standard protocol" before it speaks RCTP).

Only the RCML file and the RXID files its `UserInterface` links name are served, read once at
start: a request can name nothing else, whatever its path says (no directory walking, no file read
because a request or a document asks). h11 does the HTTP, asyncio the sockets; each connection
answers its requests in turn and closes after 30 s of silence, or when a request is not whole 10 s
after its first byte; connections beyond the caps of D-RCTP-32 are closed at once (`limits`).
"""

from __future__ import annotations

import asyncio
import html
import logging
from dataclasses import dataclass
from pathlib import Path
from urllib.parse import quote, unquote, urlsplit

import h11

from rcmlconf import __version__
from rcmlconf.markup.failure import MAX_DOCUMENT_BYTES
from rcmlconf.rcml.model import RcmlDocument
from rcmlconf.reference.server.limits import (
    DEFAULT_LIMITS,
    PeerCount,
    ServerLimits,
    connection_cap,
)

IDLE_TIMEOUT = 30.0
#: An RCML or RXID document is XML; the suffix tells which (R-XML-10).
XML_TYPE = "application/xml"
INDEX_TYPE = "text/html; charset=utf-8"
_SERVER = f"rcmlconf/{__version__}"
_READ_SIZE = 65536
#: h11 buffers at most this much of a request's head.
_MAX_HEAD = 16384

log = logging.getLogger("rcmlconf.server")


@dataclass(frozen=True, slots=True)
class Document:
    name: str
    data: bytes


def robot_files(rcml: Path, model: RcmlDocument) -> dict[str, Document]:
    """URL path -> document: the RCML file and the local RXID files it links to, by name.

    A link that leaves the RCML file's directory, or is a URL, is not served: the browser fetches
    those itself.
    """
    base = rcml.parent.resolve()
    files = {"/" + quote(rcml.name): Document(rcml.name, rcml.read_bytes())}
    for link in model.links:
        parts = urlsplit(link.href)
        if link.kind != "UserInterface" or parts.scheme or parts.netloc or not parts.path:
            continue
        path = (base / unquote(parts.path)).resolve()
        if not path.is_relative_to(base) or not path.is_file():
            continue
        if path.stat().st_size > MAX_DOCUMENT_BYTES:
            continue
        relative = path.relative_to(base).as_posix()
        files["/" + quote(relative)] = Document(relative, path.read_bytes())
    return files


def index_page(title: str, files: dict[str, Document]) -> bytes:
    items = "".join(
        f'<li><a href="{html.escape(url)}">{html.escape(doc.name)}</a></li>'
        for url, doc in files.items()
    )
    page = f"<!DOCTYPE html><title>{html.escape(title)}</title><ul>{items}</ul>\n"
    return page.encode("utf-8")


class _Held:
    """A files connection among the open connections: it never holds a session, so a full
    table may close it to make room (D-RCTP-32)."""

    __slots__ = ("transport",)

    def __init__(self, transport: asyncio.WriteTransport) -> None:
        self.transport = transport

    def evict(self) -> None:
        self.transport.abort()  # its reader then ends, and `handle` lets it go


class FileServer:
    """Serves `files` (from `robot_files`); `/` lists them."""

    def __init__(
        self,
        title: str,
        files: dict[str, Document],
        limits: ServerLimits = DEFAULT_LIMITS,
        connections: PeerCount | None = None,
    ) -> None:
        """`connections`: the count of open connections this server's count against, shared
        with RCTP's (D-RCTP-32: one cap keeps the process below its file descriptors); one of
        its own, of `limits`' size, when None."""
        self.files = files
        self._index = index_page(title, files)
        self.served = 0
        self.limits = limits
        if connections is None:
            connections = PeerCount(connection_cap(limits.connections), limits.connections_per_peer)
        self.connections = connections

    async def handle(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        peer = (writer.get_extra_info("peername") or ("?",))[0]
        held = _Held(writer.transport)
        if not self.connections.admit(peer, held, asyncio.get_running_loop().time()):
            writer.transport.abort()  # D-RCTP-32: beyond a cap, closed at once
            return
        try:
            await self._converse(reader, writer)
        except OSError as error:
            # A peer that resets the connection (even while it is told "bad request") or goes
            # silent (TimeoutError is an OSError) ends its own connection and nothing else: not
            # an error of the server's, so not a traceback on its standard error.
            log.debug("HTTP connection ended: %s", error.strerror or type(error).__name__)
        finally:
            self.connections.leave(peer, held)
            writer.close()

    async def _converse(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        """Answer the connection's requests in turn, until it closes or breaks HTTP."""
        conn = h11.Connection(h11.SERVER, max_incomplete_event_size=_MAX_HEAD)
        try:
            while True:
                event = await self._next_event(conn, reader)
                if isinstance(event, h11.Request):
                    await self._answer(conn, writer, event)
                elif isinstance(event, h11.ConnectionClosed) or event is None:
                    break
                if conn.our_state is h11.MUST_CLOSE or conn.their_state is h11.MUST_CLOSE:
                    break
                if conn.our_state is h11.DONE and conn.their_state is h11.DONE:
                    conn.start_next_cycle()
        except h11.RemoteProtocolError as error:
            if conn.our_state in (h11.IDLE, h11.SEND_RESPONSE):
                await self._send(
                    conn, writer, error.error_status_hint, b"bad request\n", "text/plain"
                )

    async def _next_event(self, conn: h11.Connection, reader: asyncio.StreamReader) -> object:
        """The next event: silence between requests may last IDLE_TIMEOUT, a request must be
        whole within the slow timeout of its first byte (TimeoutError otherwise)."""
        loop = asyncio.get_running_loop()
        started = loop.time() if conn.trailing_data[0] else None
        while True:
            event = conn.next_event()
            if event is not h11.NEED_DATA:
                return event
            wait = IDLE_TIMEOUT
            if started is not None:
                wait = started + self.limits.slow_timeout - loop.time()
            data = await asyncio.wait_for(reader.read(_READ_SIZE), max(wait, 0.0))
            if data and started is None:
                started = loop.time()
            conn.receive_data(data)

    async def _answer(
        self, conn: h11.Connection, writer: asyncio.StreamWriter, request: h11.Request
    ) -> None:
        method = request.method.decode("ascii", "replace")
        path = urlsplit(request.target.decode("ascii", "replace")).path
        if method not in ("GET", "HEAD"):
            status, body, kind = 405, b"GET or HEAD\n", "text/plain"
        else:
            status, body, kind = await self.find(path)
        await self._send(conn, writer, status, b"" if method == "HEAD" else body, kind, len(body))

    async def find(self, path: str) -> tuple[int, bytes, str]:
        """The status, body and media type a GET of `path` is answered with."""
        if path == "/":
            return 200, self._index, INDEX_TYPE
        if path in self.files:
            self.served += 1
            return 200, self.files[path].data, XML_TYPE
        return 404, b"not one of this robot's files\n", "text/plain"

    async def _send(
        self,
        conn: h11.Connection,
        writer: asyncio.StreamWriter,
        status: int,
        body: bytes,
        kind: str,
        length: int | None = None,
    ) -> None:
        headers = [
            ("Content-Type", kind),
            ("Content-Length", str(len(body) if length is None else length)),
            ("Server", _SERVER),
        ]
        if status == 405:
            headers.append(("Allow", "GET, HEAD"))
        writer.write(conn.send(h11.Response(status_code=status, headers=headers)) or b"")
        if body:
            writer.write(conn.send(h11.Data(data=body)) or b"")
        writer.write(conn.send(h11.EndOfMessage()) or b"")
        await writer.drain()
