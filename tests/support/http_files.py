"""Fixed files over HTTP on 127.0.0.1, from a thread: what a conformance harness serves a client
under test beside RCTP (a case's files index and RCML, its case list; D-RCTP-31)."""

from __future__ import annotations

import threading
from collections.abc import Iterator
from contextlib import contextmanager
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from urllib.parse import urlsplit

from support.processes import free_port

#: Path -> (body, media type).
Files = dict[str, tuple[bytes, str]]


class FileServer(ThreadingHTTPServer):
    def __init__(self, files: Files, port: int) -> None:
        super().__init__(("127.0.0.1", port), _Handler)
        self.files = files
        self.port: int = self.server_address[1]
        #: The path of every GET, in the order they came.
        self.gets: list[str] = []


class _Handler(BaseHTTPRequestHandler):
    server: FileServer

    def do_GET(self) -> None:
        path = urlsplit(self.path).path
        self.server.gets.append(path)
        if path not in self.server.files:
            self.send_error(404)
            return
        body, kind = self.server.files[path]
        self.send_response(200)
        self.send_header("Content-Type", kind)
        self.send_header("Content-Length", str(len(body)))
        self.end_headers()
        self.wfile.write(body)

    def log_message(self, format: str, *args: object) -> None:
        """Quiet: a test reads `gets`."""


@contextmanager
def http_files(files: Files, port: int = 0) -> Iterator[FileServer]:
    """Serve `files` on 127.0.0.1:`port` (0: a free one); any other path is 404."""
    with _serving(FileServer(files, port)) as server:
        yield server


@contextmanager
def files_after_free_port(files: Files, attempts: int = 5) -> Iterator[tuple[int, FileServer]]:
    """A port P nothing listens on, with `files` served at P+1, where D-RCTP-29 and D-RCTP-31
    put a server's files: (P, the files' server)."""
    for _ in range(attempts):
        port = free_port()
        try:
            server = FileServer(files, port + 1)
        except OSError:  # P+1 is taken: another P
            continue
        with _serving(server):
            yield port, server
        return
    raise AssertionError(f"no free port P with P+1 free in {attempts} attempts")


@contextmanager
def _serving(server: FileServer) -> Iterator[FileServer]:
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield server
    finally:
        server.shutdown()
        server.server_close()
        thread.join(timeout=5.0)
