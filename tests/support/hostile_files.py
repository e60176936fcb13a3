"""Hostile peers of our own clients on 127.0.0.1, each served from threads (issue 27): files
ports that trickle an answer or send a body without end, and a server that accepts and closes at
once."""

from __future__ import annotations

import itertools
import socket
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager, suppress

#: What serves one accepted connection; it returns when `stop` is set at the latest.
Serve = Callable[[socket.socket, threading.Event], None]
_HEAD = b"HTTP/1.1 200 OK\r\nContent-Type: text/html\r\n"


def close_at_once(conn: socket.socket, stop: threading.Event) -> None:
    """Accept, then close: no byte read or sent."""


def trickle(every: float) -> Serve:
    """An HTTP answer one byte each `every` seconds: its head, then a body it never ends."""

    def serve(conn: socket.socket, stop: threading.Event) -> None:
        conn.recv(65536)
        answer = itertools.chain(_HEAD + b"Content-Length: 100000\r\n\r\n", itertools.repeat(97))
        for byte in answer:
            conn.sendall(bytes([byte]))
            if stop.wait(every):
                return

    return serve


def endless(conn: socket.socket, stop: threading.Event) -> None:
    """An HTTP answer with no Content-Length (it ends when the connection does), whose body
    never ends: 64 KiB after 64 KiB, as fast as the client reads."""
    conn.recv(65536)
    conn.sendall(_HEAD + b"\r\n")
    block = b"<p>" * 21845
    while not stop.is_set():
        conn.sendall(block)


@contextmanager
def tcp_peer(serve: Serve, port: int = 0) -> Iterator[int]:
    """A listener on 127.0.0.1:`port` (0: any free one) that serves every connection with
    `serve` in a thread of its own; its port."""
    listener = socket.create_server(("127.0.0.1", port))
    listener.settimeout(0.05)  # to see `stop`: closing a socket does not end its accept
    stop = threading.Event()

    def one(conn: socket.socket) -> None:
        with conn, suppress(OSError):
            serve(conn, stop)

    def accept() -> None:
        while not stop.is_set():
            with suppress(TimeoutError):
                conn, _ = listener.accept()
                threading.Thread(target=one, args=(conn,), daemon=True).start()

    with _serving(listener, accept, stop) as port:
        yield port


@contextmanager
def rctp_and_files(files: Serve) -> Iterator[int]:
    """A port P that accepts and closes at once (an RCTP server that is there), with `files` at
    P+1, where D-RCTP-29 puts a server's files; P."""
    for _ in range(50):
        with tcp_peer(close_at_once) as port:
            try:
                served = tcp_peer(files, port + 1)
                served.__enter__()
            except OSError:  # P+1 is taken: another P
                continue
            try:
                yield port
            finally:
                served.__exit__(None, None, None)
            return
    raise AssertionError("no free pair of ports")


@contextmanager
def _serving(sock: socket.socket, run: Callable[[], None], stop: threading.Event) -> Iterator[int]:
    """`run` in a thread while the caller has `sock`'s port; then `stop` is set, the thread
    joined and the socket closed."""
    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    try:
        yield sock.getsockname()[1]
    finally:
        stop.set()
        thread.join(timeout=5.0)
        sock.close()
