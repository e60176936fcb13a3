"""The panel's web server: the page (`static/`) and its WebSocket, on one port.

`websockets` serves both: `process_request` sees every request before the upgrade, so the
`security` checks come first for the page's files and the socket alike, and a page's file is
answered there without a second web framework. Each WebSocket is one page with its own `Bridge`.
Answers say `no-store` and `no-referrer` (the token is in the page's URL: an `html` widget's
frame must not be told it), and the page's Content-Security-Policy lets it run only its own script
and connect only to its own socket (R-RXID-30: nothing of the RXID is code).
"""

from __future__ import annotations

import asyncio
import json
import logging
from collections.abc import Callable
from importlib import resources
from urllib.parse import urlsplit

from websockets.asyncio.server import Server, ServerConnection, serve
from websockets.datastructures import Headers
from websockets.exceptions import ConnectionClosed
from websockets.http11 import Request, Response

from rcmlconf.browse.bridge import Bridge
from rcmlconf.browse.messages import MAX_MESSAGE
from rcmlconf.browse.security import Guard

SOCKET_PATH = "/socket"
#: The page's files: name -> media type.
FILES = {
    "index.html": "text/html; charset=utf-8",
    "panel.js": "text/javascript; charset=utf-8",
    "panel.css": "text/css; charset=utf-8",
}
#: Where an `html` widget's frame, a `netmeeting` video and a window's background may come from
#: (http(s), as `panel.shown_url` allows); the page's own script, style and socket only.
POLICY = (
    "default-src 'none'; script-src 'self'; style-src 'self'; connect-src 'self'; "
    "img-src http: https: data:; media-src http: https:; frame-src http: https:; "
    "base-uri 'none'; form-action 'none'; frame-ancestors 'none'"
)
_COMMON = [
    ("Cache-Control", "no-store"),
    ("Referrer-Policy", "no-referrer"),
    ("X-Content-Type-Options", "nosniff"),
]

log = logging.getLogger("rcmlconf.browse")


class _Quiet(logging.Filter):
    """websockets' own log (connections opened and closed, a failed handshake of a port scanner
    or a browser gone) is for -vv, and never a traceback on the user's terminal."""

    def filter(self, record: logging.LogRecord) -> bool:
        record.exc_info, record.exc_text = None, None
        record.levelno, record.levelname = logging.DEBUG, "DEBUG"
        return log.isEnabledFor(logging.DEBUG)


_wire_log = logging.getLogger("rcmlconf.browse.websockets")
_wire_log.addFilter(_Quiet())


def _file(name: str) -> bytes:
    return resources.files("rcmlconf.browse").joinpath("static", name).read_bytes()


class PanelServer:
    def __init__(self, guard: Guard, bridge: Callable[[str], Bridge]) -> None:
        """`bridge` makes a page's bridge, given the page's name for log lines."""
        self.guard = guard
        self._bridge = bridge
        self._pages: set[asyncio.Task[None]] = set()
        self._count = 0
        self.server: Server | None = None

    async def start(self, host: str, port: int) -> int:
        """Listen; the port listened on. OSError when it cannot."""
        self.server = await serve(
            self._page,
            host,
            port,
            process_request=self._request,
            max_size=MAX_MESSAGE,
            # permessage-deflate would squeeze messages of a hundred bytes at 62.5 Hz a page,
            # costing both ends CPU and time for nothing on a loopback link (issue 20, Speed).
            compression=None,
            logger=_wire_log,
            server_header=None,
        )
        sockets = list(self.server.sockets)
        number: int = sockets[0].getsockname()[1]
        self.guard.port = number
        return number

    async def stop(self) -> None:
        """Every page's sessions end (BYE), then the server."""
        for task in list(self._pages):
            task.cancel()
        await asyncio.gather(*self._pages, return_exceptions=True)
        if self.server is not None:
            self.server.close()
            await self.server.wait_closed()

    def _request(self, connection: ServerConnection, request: Request) -> Response | None:
        socket = (request.headers.get("Upgrade") or "").lower() == "websocket"
        refusal = self.guard.refusal(request.path, request.headers.get, socket)
        if refusal is not None:
            log.warning("refused %s: %s", urlsplit(request.path).path, refusal)
            return _answer(connection, 403, refusal)
        path = urlsplit(request.path).path
        if socket:
            return None if path == SOCKET_PATH else _answer(connection, 404, "no such socket")
        name = "index.html" if path == "/" else path.lstrip("/")
        if name not in FILES:
            return _answer(connection, 404, "not one of the panel's files")
        body = _file(name)
        if name == "index.html":
            # The token goes into the page's links to its own files (they are checked too).
            body = body.replace(b"{{token}}", self.guard.token.encode())
        headers = Headers([("Content-Type", FILES[name]), ("Content-Security-Policy", POLICY)])
        headers.update(_COMMON)
        headers["Content-Length"] = str(len(body))
        return Response(200, "OK", headers, body)

    async def _page(self, connection: ServerConnection) -> None:
        self._count += 1
        name = f"page {self._count}"
        log.info("%s opened", name)
        bridge = self._bridge(name)
        task = asyncio.current_task()
        assert task is not None
        self._pages.add(task)
        work = [
            asyncio.ensure_future(bridge.run()),
            asyncio.ensure_future(_send(connection, bridge)),
            asyncio.ensure_future(_receive(connection, bridge)),
        ]
        try:
            await asyncio.wait(work, return_when=asyncio.FIRST_COMPLETED)
        finally:
            for job in work:
                job.cancel()
            await asyncio.gather(*work, return_exceptions=True)  # the bridge says BYE
            self._pages.discard(task)
            log.info("%s closed", name)


async def _send(connection: ServerConnection, bridge: Bridge) -> None:
    try:
        while True:
            for message in await bridge.outbox.take():
                await connection.send(json.dumps(message))
    except ConnectionClosed:
        return


async def _receive(connection: ServerConnection, bridge: Bridge) -> None:
    try:
        async for data in connection:
            bridge.receive(data)
    except ConnectionClosed:
        return


def _answer(connection: ServerConnection, status: int, text: str) -> Response:
    response = connection.respond(status, text + "\n")
    response.headers.update(_COMMON)
    return response
