"""Hostile peers of our own clients on 127.0.0.1, each served from threads (issue 27): files
ports that trickle an answer or send a body without end, a server that accepts and closes at
once, and an RSP robot that never answers HELLO, floods garbage or UPLINKs, welcomes and then
says nothing, or welcomes and says BYE."""

from __future__ import annotations

import itertools
import os
import socket
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager, suppress

from rcmlconf.rsp.codec.header import TYPE_AT, PacketType
from rcmlconf.rsp.model import RobotModel
from rcmlconf.rsp.session.robot import RobotEndpoint
from support.rsp_flood import spoofed

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


#: UPLINKs a flooding robot sends between sleeps of 1 ms: some 20,000 a second, which leaves
#: the other processes of a test a core.
FLOOD_BURST = 20
#: What a hostile robot does once it has a datagram from the local system.
ROBOT_MODES = ("silent", "garbage", "welcome", "bye", "uplinks")


@contextmanager
def hostile_robot(model: RobotModel, mode: str) -> Iterator[int]:
    """An RSP robot of `model` on 127.0.0.1 that is hostile as `mode` says: `silent` never
    answers; `garbage` answers every datagram with 20 of random bytes; `welcome` answers HELLO
    with WELCOME, then says nothing; `bye` welcomes, then ends the session at once (BYE);
    `uplinks` welcomes, then sends UPLINKs as fast as it can, each a new packet. Its port."""
    assert mode in ROBOT_MODES, mode
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    sock.settimeout(0.05)
    stop = threading.Event()
    robot = RobotEndpoint(model)

    def answer(data: bytes, peer: tuple[str, int]) -> list[bytes]:
        """The reference robot's answer to a HELLO; in `uplinks`, its first UPLINK too (the
        empty one of the fifth period, D-RSP-13)."""
        now = time.monotonic()
        robot.receive_datagram(data, peer, now)
        if robot.session is not None and mode == "bye":
            robot.close(now)
        for _ in range(5 if robot.session is not None and mode == "uplinks" else 0):
            robot.handle_timer(robot.session.beat.next)
        return [datagram for datagram, _ in robot.datagrams_to_send(now)]

    def run() -> None:
        uplink, peer, sent = b"", ("", 0), 0
        with suppress(OSError):
            while not stop.is_set():
                if uplink:  # the same UPLINK, each time a newer packet (D-RSP-11)
                    sent += 1
                    sock.sendto(spoofed(uplink, sent), peer)
                    if sent % FLOOD_BURST == 0:
                        time.sleep(0.001)
                    continue
                try:
                    data, peer = sock.recvfrom(65536)
                except TimeoutError:
                    continue
                if mode == "garbage":
                    for _ in range(20):
                        sock.sendto(os.urandom(1 + data[0] % 200), peer)
                elif mode != "silent" and robot.session is None:
                    for datagram in answer(data, peer):
                        sock.sendto(datagram, peer)
                        if datagram[TYPE_AT] == PacketType.UPLINK:
                            uplink = datagram

    with _serving(sock, run, stop) as port:
        yield port


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
