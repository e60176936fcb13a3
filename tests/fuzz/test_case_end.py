"""How a server-role case ends (D-FUZZ-1): the fuzzer's FIN once every byte it sent frames
whole, and the server's close then ends the case as "finished"; no FIN after a request cut
short. Small servers on 127.0.0.1 that answer each request 200 and react to the end of their
input as told."""

from __future__ import annotations

import socket
import struct
import threading
from collections.abc import Iterator
from contextlib import contextmanager

from rcmlconf.fuzz.rctp_exec import RctpRunner
from rcmlconf.fuzz.steps import Step, TestCase

CONNECT = b"CONNECT / RCTP/2.0\r\nCSeq: 1\r\n\r\n"
ANSWER = b"RCTP/2.0 200 OK\r\nCSeq: 1\r\nSession: s1\r\n\r\n"
#: Every wait of these servers ends within this, seconds.
BOUND = 5.0


@contextmanager
def server(on_end: str) -> Iterator[tuple[tuple[str, int], threading.Event]]:
    """One connection: answer CONNECT 200, then read until the end of input and "close",
    "reset", or "linger" (keep the connection open). Without an end of input it waits until the
    test is done (the event)."""
    listener = socket.create_server(("127.0.0.1", 0))
    listener.settimeout(BOUND)
    done = threading.Event()

    def serve() -> None:
        with listener, listener.accept()[0] as conn:
            conn.settimeout(BOUND)
            seen = b""
            while b"\r\n\r\n" not in seen:
                seen += conn.recv(4096)
            conn.sendall(ANSWER)
            conn.settimeout(0.05)
            while not done.is_set():
                try:
                    if conn.recv(4096) == b"":
                        break
                except TimeoutError:
                    continue
            else:
                return
            if on_end == "reset":
                conn.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
            elif on_end == "linger":
                done.wait(BOUND)

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    try:
        yield listener.getsockname()[:2], done
    finally:
        done.set()
        thread.join(BOUND)


def ended(on_end: str, *steps: bytes) -> str:
    with server(on_end) as (address, _):
        runner = RctpRunner(address, wait=BOUND)
        try:
            case = TestCase("session", (Step("control", CONNECT),), tuple(
                Step("control", data, kind="bytes") for data in steps
            ))  # fmt: skip
            out = runner.run(case)
        finally:
            runner.close()
    assert out.statuses == [200]
    return out.end


def test_a_close_after_the_fuzzers_fin_ends_the_case_as_finished() -> None:
    assert ended("close") == "finished"


def test_a_reset_after_the_fin_is_still_a_reset() -> None:
    assert ended("reset") == "reset"


def test_a_server_that_keeps_the_connection_open_ends_the_case_open() -> None:
    assert ended("linger") == "open"


def test_no_fin_after_a_request_cut_short() -> None:
    # The server would close on the end of its input: it gets none, so the case ends open.
    assert ended("close", b"READ / RCTP/2.0\r\nCSeq: 2\r\n") == "open"
