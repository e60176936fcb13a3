"""Hostile RCTP servers on 127.0.0.1, each a thread with a real listening socket, for `run
--target` to be judged against (tests/conformance/test_hostile_resets.py):

- `reset`: accepts each connection and resets it at once (SO_LINGER 0, then close);
- `reset-after-request`: reads the first bytes of each connection, then resets it;
- `silent`: accepts and holds each connection, sending nothing;
- `dies`: answers every request of its first `after` connections 503 (with its CSeq), then
  stops listening, as a server that crashed mid-run: the connections the kernel had taken for
  it are reset, every later one is refused.

Each is bounded: a held connection lasts until the server stops, at most HELD of them, and the
thread ends at the `with` block's end or after LIFETIME seconds."""

from __future__ import annotations

import re
import socket
import struct
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager, suppress

LIFETIME = 20.0
HELD = 256
_CSEQ = re.compile(rb"\r\nCSeq:[ \t]*(\d{1,9})", re.IGNORECASE)
_503 = b"RCTP/2.0 503 Service Unavailable\r\nCSeq: %s\r\n\r\n"


def _reset(connection: socket.socket) -> None:
    connection.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
    connection.close()


def _read_then_reset(connection: socket.socket) -> None:
    """The connection's first bytes read (a second at most), then it is reset."""
    connection.settimeout(1.0)
    with suppress(OSError):
        connection.recv(65536)
    _reset(connection)


def _answer_503(connection: socket.socket, stop: threading.Event) -> None:
    """Each request of the connection answered 503 with its CSeq, until the peer closes."""
    connection.settimeout(0.2)
    with connection:
        while not stop.is_set():
            try:
                data = connection.recv(65536)
            except TimeoutError:
                continue
            except OSError:
                return
            if not data:
                return
            with suppress(OSError):  # one answer a request; one for bytes that have no CSeq
                for cseq in _CSEQ.findall(data) or [b"0"]:
                    connection.sendall(_503 % cseq)


def _serve(listening: socket.socket, mode: str, after: int, stop: threading.Event) -> None:
    held: list[socket.socket] = []
    served = 0
    deadline = time.monotonic() + LIFETIME
    listening.settimeout(0.05)
    try:
        while not stop.is_set() and time.monotonic() < deadline:
            try:
                connection, _ = listening.accept()
            except TimeoutError:
                continue
            served += 1
            if mode == "reset":
                _reset(connection)
            elif mode == "reset-after-request":
                threading.Thread(target=_read_then_reset, args=(connection,), daemon=True).start()
            elif mode == "silent" and len(held) < HELD:
                held.append(connection)
            elif mode == "dies":
                args = (connection, stop)
                threading.Thread(target=_answer_503, args=args, daemon=True).start()
                if served >= after:
                    return  # the finally closes the listening socket: refused from now on
            else:
                connection.close()
    finally:
        listening.close()
        for connection in held:
            connection.close()


@contextmanager
def hostile(mode: str, after: int = 0) -> Iterator[int]:
    """A hostile server doing `mode` (the module's docstring) while the block runs: its port."""
    listening = socket.socket()
    listening.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    listening.bind(("127.0.0.1", 0))
    listening.listen(128)
    port: int = listening.getsockname()[1]
    stop = threading.Event()
    thread = threading.Thread(target=_serve, args=(listening, mode, after, stop), daemon=True)
    thread.start()
    try:
        yield port
    finally:
        stop.set()
        thread.join(LIFETIME)
