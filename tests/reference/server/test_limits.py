"""What one peer may take from the reference server (D-RCTP-32): slow connections closed, the
caps on connections and sessions, a pipelined burst answered whole while others are served, and
a server out of file descriptors that says so in a line and goes on."""

from __future__ import annotations

import asyncio
import contextlib
import errno
import gc
import json
import logging
import resource
import socket
import subprocess
import time
import weakref
from pathlib import Path
from urllib.parse import urlsplit

import pytest
from support.processes import COMMAND, running
from support.robots import TESTBOT
from support.servers import Raw, RawSession, run, serving
from support.waits import until

from rcmlconf.reference.datagrams import DATAGRAMS_A_TURN, RECEIVE_BUFFER
from rcmlconf.reference.server.adapter import ReferenceServer
from rcmlconf.reference.server.limits import ACCEPTS_A_TURN, ServerLimits

#: What begins an answer (READ / is refused: 405, as good as any answer here).
ANSWER = b"RCTP/2.0 "
#: A slow timeout short enough for a test (R-RCTP-67's floor is 10 s; `serve` warns below it).
SLOW = 0.5


async def _from(server_port: int, source: str) -> Raw:
    """A control connection from another loopback address: another peer."""
    reader, writer = await asyncio.open_connection("127.0.0.1", server_port, local_addr=(source, 0))
    return Raw(reader, writer)


@run
async def test_a_connection_without_connect_is_closed_after_the_slow_timeout() -> None:
    async with serving(limits=ServerLimits(slow_timeout=SLOW)) as server:
        idle = await Raw.open(server)
        assert await idle.closed(timeout=5.0)


@run
async def test_a_request_not_whole_is_closed_after_the_slow_timeout() -> None:
    async with serving(limits=ServerLimits(slow_timeout=SLOW)) as server:
        session = await RawSession.open(server)
        await session.raw.send(b"READ / RCTP/2.0\r\nCSeq: 2\r\n")  # the head never ends
        assert await session.raw.closed(timeout=5.0)


@run
async def test_a_session_quiet_between_requests_is_kept() -> None:
    async with serving(limits=ServerLimits(slow_timeout=SLOW)) as server:
        session = await RawSession.open(server)
        await asyncio.sleep(3 * SLOW)  # the session's own timeout (60 s) is what applies
        answer = await session.ask("CONNECT", "/", [])
        assert answer.status == 200, answer


@run
async def test_connections_beyond_the_peer_cap_are_closed_at_once_and_others_served() -> None:
    async with serving(limits=ServerLimits(connections_per_peer=3)) as server:
        kept = [await Raw.open(server) for _ in range(3)]
        beyond = await Raw.open(server)
        assert await beyond.closed(timeout=5.0)
        # Another address is another peer: served.
        other = await _from(server.port, "127.0.0.2")
        await other.send(b"CONNECT / RCTP/2.0\r\nCSeq: 1\r\n\r\n")
        assert (await other.response()).status == 200
        # A connection that leaves makes room again.
        kept.pop().close()
        await asyncio.sleep(0.2)
        again = await Raw.open(server)
        await again.send(b"CONNECT / RCTP/2.0\r\nCSeq: 1\r\n\r\n")
        assert (await again.response()).status == 200
        for raw in (*kept, other, again):
            raw.close()


@run
async def test_a_connect_beyond_the_peer_session_cap_is_answered_503() -> None:
    async with serving(limits=ServerLimits(sessions_per_peer=2)) as server:
        sessions = [await RawSession.open(server) for _ in range(2)]
        third = await Raw.open(server)
        await third.send(b"CONNECT / RCTP/2.0\r\nCSeq: 1\r\n\r\n")
        answer = await third.response()
        assert answer.status == 503, answer
        assert b"sessions" in answer.body
        # One ends (BYE): its place is free again, on the same connection.
        assert (await sessions[0].ask("BYE", "*")).status == 200
        await asyncio.sleep(0.2)
        await third.send(b"CONNECT / RCTP/2.0\r\nCSeq: 2\r\n\r\n")
        assert (await third.response()).status == 200
        for raw in (third, *(s.raw for s in sessions[1:])):
            raw.close()


@run
async def test_a_pipelined_burst_is_answered_in_order_and_in_full_while_another_is_served() -> None:
    async with serving(limits=ServerLimits(slice_bytes=1024)) as server:
        flood = await RawSession.open(server)
        other = await RawSession.open(server)
        count = 3000
        burst = b"".join(
            f"CONNECT / RCTP/2.0\r\nCSeq: {cseq}\r\nSession: {flood.session}\r\n\r\n".encode()
            for cseq in range(2, count + 2)
        )
        flood.raw.writer.write(burst)  # not drained: the answers are read below
        # The other session's request, sent once the burst is on its way, is answered.
        await asyncio.sleep(0)
        assert (await other.ask("CONNECT", "/")).status == 200
        cseqs = [int((await flood.raw.response()).headers.get("CSeq") or 0) for _ in range(count)]
        assert cseqs == list(range(2, count + 2))
        for raw in (flood.raw, other.raw):
            raw.close()


def _limited_nofile() -> None:
    resource.setrlimit(resource.RLIMIT_NOFILE, (96, 96))


def test_with_few_file_descriptors_the_cap_keeps_the_server_accepting(tmp_path: Path) -> None:
    """With 96 files allowed, the connection cap is 32 (the rest kept back): beyond it each new
    connection closes an older one without a session (none has one here), so accepting never
    runs out of descriptors, and the closes are a line in the log now and then, never a
    traceback."""
    ready = tmp_path / "ready.json"
    command = [*COMMAND, "serve", str(TESTBOT), "--port", "0", "--http-port", "0"]
    process = subprocess.Popen(
        [*command, "--ready-file", str(ready), "--max-connections", "1000000"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=_limited_nofile,
    )
    sockets: list[socket.socket] = []
    try:
        deadline = time.monotonic() + 20
        while not ready.exists():
            assert process.poll() is None
            assert time.monotonic() < deadline
            time.sleep(0.02)
        port = urlsplit(json.loads(ready.read_text())["rctp"]).port
        assert port is not None
        for _ in range(120):
            sockets.append(socket.create_connection(("127.0.0.1", port), timeout=5))
        # The server takes them from its queue a few a turn of its loop, each beyond the cap
        # closing an older one at once.
        assert _closed_by_the_server(sockets, at_least=120 - 32, within=10.0)
        for sock in sockets:
            sock.close()
        sockets.clear()
        # Once the server has seen them go (a moment, on a loaded machine), a client is served.
        assert _served(port, within=10.0)
    finally:
        for sock in sockets:
            sock.close()
        process.terminate()
        _out, err = process.communicate(timeout=20)
    assert "Traceback" not in err, err
    assert 1 <= err.count("connections closed to make room") <= 2, err


def _closed_by_the_server(sockets: list[socket.socket], at_least: int, within: float) -> bool:
    """Whether at least `at_least` of `sockets` are closed by the server within `within` s."""
    deadline = time.monotonic() + within
    closed: set[int] = set()
    while time.monotonic() < deadline:
        for index, sock in enumerate(sockets):
            if index not in closed and _closed(sock):
                closed.add(index)
        if len(closed) >= at_least:
            return True
        time.sleep(0.05)
    return False


def _closed(sock: socket.socket) -> bool:
    sock.setblocking(False)  # a socket with a timeout would wait for data first
    try:
        return sock.recv(1) == b""
    except BlockingIOError:
        return False
    except OSError:  # reset
        return True


def _served(port: int, within: float) -> bool:
    """Whether a CONNECT on a new connection is answered 200 within `within` seconds (a
    connection the server refused, beyond its cap, is closed at once: tried again)."""
    deadline = time.monotonic() + within
    while time.monotonic() < deadline:
        with contextlib.suppress(OSError), socket.create_connection(("127.0.0.1", port), 5) as c:
            c.sendall(b"CONNECT / RCTP/2.0\r\nCSeq: 1\r\n\r\n")
            if c.recv(4096).startswith(b"RCTP/2.0 200 "):
                return True
        time.sleep(0.1)
    return False


def test_an_accept_out_of_descriptors_is_one_line_without_traceback(
    caplog: pytest.LogCaptureFixture,
) -> None:
    """What asyncio hands the loop's exception handler when accept() fails with EMFILE (it
    then tries again by itself a second later): the server's handler logs one line an
    interval and passes anything else on."""

    async def check() -> None:
        async with serving():
            loop = asyncio.get_running_loop()
            failed = OSError(errno.EMFILE, "Too many open files")
            context = {"message": "socket.accept() out of system resource", "exception": failed}
            for _ in range(50):
                loop.call_exception_handler(context)
        # Once the server stops, the handler there was before (none) is back.
        assert asyncio.get_running_loop().get_exception_handler() is None

    with caplog.at_level(logging.WARNING, logger="rcmlconf.server"):
        asyncio.run(asyncio.wait_for(check(), 30))
    lines = [r.getMessage() for r in caplog.records if "cannot accept" in r.getMessage()]
    assert len(lines) == 1, lines
    assert "Too many open files" in lines[0]
    assert not any(r.exc_info for r in caplog.records)


def test_serve_warns_of_limits_below_the_floor(tmp_path: Path) -> None:
    with running(
        tmp_path, "serve", str(TESTBOT), "--port", "0", "--http-port", "0", "--slow-timeout", "2"
    ) as server:
        _status, _out, err = server.stop()
    assert "a slow connection closed after 2 s: below R-RCTP-67's floor" in err, err


@run
async def test_the_files_server_closes_a_slow_request_and_refuses_beyond_the_peer_cap() -> None:
    limits = ServerLimits(slow_timeout=SLOW, connections_per_peer=2)
    async with serving(limits=limits) as server:
        assert server.http_port is not None
        slow = await asyncio.open_connection("127.0.0.1", server.http_port)
        slow[1].write(b"GET / HTTP/1.1\r\nHost: x\r\n")  # the head never ends
        assert await Raw(*slow).closed(timeout=5.0)
        kept = [await asyncio.open_connection("127.0.0.1", server.http_port) for _ in range(2)]
        beyond = Raw(*await asyncio.open_connection("127.0.0.1", server.http_port))
        assert await beyond.closed(timeout=5.0)
        reader, writer = kept[0]
        writer.write(b"GET / HTTP/1.1\r\nHost: x\r\n\r\n")
        assert (await asyncio.wait_for(reader.readline(), 5.0)).startswith(b"HTTP/1.1 200 ")
        for _, other in kept:
            other.close()


@run
async def test_a_burst_of_connects_waits_in_the_queue_and_is_accepted_a_few_a_turn() -> None:
    """D-RCTP-32: 200 connections made while the server's loop does not run all complete (the
    kernel's queue holds them), and the loop then takes them ACCEPTS_A_TURN a turn, the other
    work of each turn (the streams' beats) in between; none is lost."""
    async with serving() as server:
        burst = []
        try:
            for _ in range(200):  # blocking: the loop, the server's, does not run meanwhile
                burst.append(socket.create_connection(("127.0.0.1", server.port), timeout=2.0))
            for turn in range(1, 6):
                await asyncio.sleep(0)  # one turn of the loop
                assert server.connections.total <= turn * ACCEPTS_A_TURN
            assert await until(lambda: server.connections.total == 200)
        finally:
            for sock in burst:
                sock.close()


@run
async def test_rctp_and_files_connections_count_against_one_cap() -> None:
    """The files server's connections and RCTP's share the cap (D-RCTP-32), so that together
    they stay below the process's file descriptors: with two sessions and a files connection
    open, a new connection fills a cap of 3 and closes the files one, which holds no session,
    to make room; with three sessions, a new one is closed."""
    async with serving(limits=ServerLimits(connections=3)) as server:
        assert server.http_port is not None
        sessions = [await RawSession.open(server) for _ in range(2)]
        files = Raw(*await asyncio.open_connection("127.0.0.1", server.http_port))
        assert await until(lambda: server.connections.total == 3)
        again = await RawSession.open(server)
        assert await files.closed(timeout=5.0)
        assert await until(lambda: server.connections.total == 3)
        beyond = Raw(*await asyncio.open_connection("127.0.0.1", server.http_port))
        assert await beyond.closed(timeout=5.0)
        for session in (*sessions, again):
            assert (await session.ask("CONNECT", "/")).status == 200
            session.raw.close()


@run
async def test_the_data_socket_is_read_several_datagrams_a_turn() -> None:
    """A flood at the data port is drained DATAGRAMS_A_TURN a wake-up from a large receive
    buffer, not one a turn of the loop: the sessions' own datagrams are not crowded out of the
    buffer (D-RCTP-32)."""
    async with serving() as server:
        udp = server._udp
        assert udp is not None
        rmem_max = int(Path("/proc/sys/net/core/rmem_max").read_text())
        asked = udp.sock.getsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF)
        assert asked >= min(RECEIVE_BUFFER, rmem_max)  # Linux reports twice what it keeps
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as flood:
            for index in range(300):  # no session's tag: dropped unanswered (R-RCTP-42)
                flood.sendto(b"\x02\x01" + index.to_bytes(14, "big"), ("127.0.0.1", udp.port))
            for _ in range(2):
                await asyncio.sleep(0)
            assert server.data.unclaimed > 2  # more than one a turn
            assert DATAGRAMS_A_TURN > 2
            assert await until(lambda: server.data.unclaimed == 300)


@run
async def test_large_requests_take_turns_while_small_ones_are_served() -> None:
    """D-RCTP-32: a request whose body holds more than `large_bytes` takes one of
    `large_requests` places; one beyond waits, unread, until the place is left, and then goes on;
    meanwhile a small request on another connection is answered."""
    limits = ServerLimits(large_bytes=1024, large_requests=1)
    body = bytes(64 * 1024)
    head = b"CONNECT / RCTP/2.0\r\nCSeq: 1\r\nContent-Length: %d\r\n\r\n" % len(body)
    async with serving(limits=limits) as server:
        first, second = await Raw.open(server), await Raw.open(server)
        await first.send(head + body[:8192])  # a place taken, the body not whole
        assert await until(lambda: server.large.held == 1)
        await second.send(head + body[:8192])
        assert await until(lambda: server.large.waiting == 1)
        small = await RawSession.open(server)  # served while the second waits
        assert (await small.ask("CONNECT", "/")).status == 200
        assert server.large.waiting == 1
        await first.send(body[8192:])
        assert (await first.response()).status == 200
        assert await until(lambda: server.large.waiting == 0)  # the second's turn
        await second.send(body[8192:])
        assert (await second.response()).status == 200
        for raw in (first, second, small.raw):
            raw.close()


@run
async def test_a_peer_that_does_not_read_is_not_read_and_then_answered_in_full() -> None:
    """The answers to a pipelined burst fill the connection's write buffer while the peer does
    not read: the server stops reading it, and once the peer reads, goes on with the rest of the
    burst, every request answered in order."""
    async with serving() as server:
        sock = socket.socket()
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)  # a small window
        sock.setblocking(False)
        await asyncio.get_running_loop().sock_connect(sock, ("127.0.0.1", server.port))
        flood = Raw(*await asyncio.open_connection(sock=sock))
        await flood.send(b"CONNECT / RCTP/2.0\r\nCSeq: 1\r\n\r\n")
        session = (await flood.response()).headers.get("Session")
        for control in server.controls.values():  # a slow network: small kernel buffers
            assert control.transport is not None
            server_side = control.transport.get_extra_info("socket")
            server_side.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, 4096)
        count = 6000  # answers well beyond what the client's buffers take
        flood.writer.write(
            b"".join(
                f"CONNECT / RCTP/2.0\r\nCSeq: {cseq}\r\nSession: {session}\r\n\r\n".encode()
                for cseq in range(2, count + 2)
            )
        )

        # Its answers over asyncio's high-water mark, the connection is paused.
        assert await until(lambda: any(c._write_paused for c in server.controls.values()))
        cseqs = [int((await flood.response()).headers.get("CSeq") or 0) for _ in range(count)]
        assert cseqs == list(range(2, count + 2))
        flood.close()


@run
async def test_a_peer_with_many_requests_at_once_does_not_hold_up_another() -> None:
    """D-RCTP-32: 400 connections of one address have a CONNECT ready at once, then one of
    another address: its answer comes before the 400 are all answered, the work of a turn
    being bounded and the peers served in turn (`turns`)."""
    count = 400
    limits = ServerLimits(connections_per_peer=count, sessions_per_peer=count)
    async with serving(limits=limits) as server:
        flood: list[socket.socket] = []
        try:
            for _ in range(count):
                flood.append(
                    socket.create_connection(
                        ("127.0.0.1", server.port), timeout=2.0, source_address=("127.0.0.2", 0)
                    )
                )
            other = await Raw.open(server)
            assert await until(lambda: server.connections.total == count + 1)
            # Sent while the loop does not run: all ready in the same turn, the other last.
            for sock in flood:
                sock.sendall(b"CONNECT / RCTP/2.0\r\nCSeq: 1\r\n\r\n")
            other.writer.write(b"CONNECT / RCTP/2.0\r\nCSeq: 1\r\n\r\n")
            assert (await other.response()).status == 200
            answered = sum(1 for sock in flood if _has_data(sock))
            assert answered < count
            other.close()
        finally:
            for sock in flood:
                sock.close()


def _has_data(sock: socket.socket) -> bool:
    sock.setblocking(False)
    try:
        return bool(sock.recv(1, socket.MSG_PEEK))
    except BlockingIOError:
        return False


@run
async def test_a_closed_connection_and_its_session_are_freed_without_the_collector() -> None:
    """No reference cycle keeps a closed connection's session (and its buffers, up to a 4 MiB
    request's) for the collector's next pass: the server process collects seldom (`collector`)."""
    gc.disable()
    try:
        async with serving() as server:
            session = await RawSession.open(server)
            freed = weakref.ref(next(iter(server.controls)))
            session.raw.close()
            assert await until(lambda: not server.controls)
            assert await until(lambda: freed() is None)
    finally:
        gc.enable()


async def _connected(server_port: int, rcvbuf: int = 0) -> tuple[socket.socket, str]:
    """A blocking client socket with a session (and a small receive buffer when asked)."""
    sock = socket.socket()
    if rcvbuf:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, rcvbuf)
    sock.settimeout(5.0)
    sock.connect(("127.0.0.1", server_port))
    sock.sendall(b"CONNECT / RCTP/2.0\r\nCSeq: 1\r\n\r\n")
    answer = b""
    while b"\r\n\r\n" not in answer:
        answer += await asyncio.get_running_loop().run_in_executor(None, sock.recv, 4096)
    return sock, answer.split(b"Session: ")[1].split(b";")[0].decode()


def _reads(session: str, count: int, first: int = 2) -> bytes:
    return b"".join(
        f"READ / RCTP/2.0\r\nCSeq: {cseq}\r\nSession: {session}\r\n\r\n".encode()
        for cseq in range(first, first + count)
    )


def _small_send_buffers(server: ReferenceServer) -> None:
    """A slow network: the server's kernel buffers small, its answers pile up sooner."""
    for control in server.controls.values():
        assert control.transport is not None
        server_side = control.transport.get_extra_info("socket")
        server_side.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, 4096)


def _reset(sock: socket.socket) -> bool:
    """Whether reading `sock` to its end meets a reset (what a server that gave up sends)."""
    sock.settimeout(5.0)
    try:
        while sock.recv(65536):
            pass
    except ConnectionResetError:
        return True
    return False


@run
async def test_a_half_closed_burst_is_answered_in_slices_in_order_and_in_full() -> None:
    """D-RCTP-32: a burst of pipelined requests followed by the peer's half-close is answered
    like any burst, a slice a turn while another peer is served, then the connection closes."""
    async with serving(limits=ServerLimits(slice_bytes=1024)) as server:
        sock, session = await _connected(server.port)
        other = await _from(server.port, "127.0.0.2")
        count = 500  # about 40 slices
        # Sent while the loop does not run: the burst and the half-close wait together.
        sock.sendall(_reads(session, count))
        sock.shutdown(socket.SHUT_WR)
        other.writer.write(b"CONNECT / RCTP/2.0\r\nCSeq: 1\r\n\r\n")
        assert (await other.response()).status == 200
        assert _has_data(sock)
        sock.setblocking(True)
        sock.settimeout(5.0)
        early = sock.recv(1 << 20, socket.MSG_PEEK).count(b"RCTP/2.0 ")
        assert early < count  # the other peer was answered before the burst's end
        flood = Raw(*await asyncio.open_connection(sock=sock))
        cseqs = [int((await flood.response()).headers.get("CSeq") or 0) for _ in range(count)]
        assert cseqs == list(range(2, count + 2))
        assert await flood.closed()
        other.close()
        flood.close()


@run
async def test_a_peer_that_takes_no_answers_is_reset_after_the_slow_timeout() -> None:
    """D-RCTP-32: reading paused because the peer takes none of its answers, the peer has the
    slow timeout to take some; then the connection is reset (its answers would never leave)
    and its descriptor is free."""
    async with serving(limits=ServerLimits(slow_timeout=SLOW)) as server:
        sock, session = await _connected(server.port, rcvbuf=4096)
        _small_send_buffers(server)
        sock.setblocking(False)
        with contextlib.suppress(BlockingIOError):
            sock.send(_reads(session, 6000))  # what the kernel takes
        assert await until(lambda: any(c._write_paused for c in server.controls.values()))
        assert await until(lambda: server.connections.total == 0)
        assert not server.controls
        assert _reset(sock)
        sock.close()


@run
async def test_a_half_closed_peer_whose_answers_do_not_leave_is_reset() -> None:
    """D-RCTP-32: after a half-close the server closes once its last answers have left; a
    peer that does not take them has the slow timeout, and until then the connection counts
    against the caps; then it is reset."""
    async with serving(limits=ServerLimits(slow_timeout=SLOW)) as server:
        sock, session = await _connected(server.port, rcvbuf=4096)
        _small_send_buffers(server)
        sock.sendall(_reads(session, 250))  # answers beyond the kernel's buffers, within asyncio's
        sock.shutdown(socket.SHUT_WR)
        assert await until(lambda: all(c.closing for c in server.controls.values()))
        assert server.connections.total == 1  # closing, its answers unsent: still counted
        assert await until(lambda: server.connections.total == 0)
        assert _reset(sock)
        sock.close()


@run
async def test_a_large_request_waiting_for_a_place_is_not_closed_as_slow() -> None:
    """D-RCTP-32: the time a large request waits, unread, for a place is the server's, not its
    peer's: it does not count toward the slow timeout."""
    slow = 1.0
    limits = ServerLimits(slow_timeout=slow, large_bytes=1024, large_requests=1)
    body = bytes(64 * 1024)
    head = b"CONNECT / RCTP/2.0\r\nCSeq: 1\r\nContent-Length: %d\r\n\r\n" % len(body)
    async with serving(limits=limits) as server:
        first, second = await Raw.open(server), await Raw.open(server)
        await first.send(head + body[:8192])
        assert await until(lambda: server.large.held == 1)
        await second.send(head + body[:8192])  # waits for the place, unread
        assert await until(lambda: server.large.waiting == 1)
        await asyncio.sleep(0.6 * slow)
        await first.send(body[8192:])  # the first, whole within its slow timeout
        assert (await first.response()).status == 200
        assert await until(lambda: server.large.waiting == 0)
        await asyncio.sleep(0.6 * slow)  # the second's first byte now more than `slow` ago
        await second.send(body[8192:])
        assert (await second.response()).status == 200
        for raw in (first, second):
            raw.close()


@run
async def test_a_peer_with_costly_work_gets_a_fair_share_of_time_not_of_turns() -> None:
    """D-RCTP-32: the queues are served by the time their work takes, not a piece each in turn:
    while one peer's burst of 3,000 READs (slices of about 55) and another peer's 200
    connections (a CONNECT each, a few READs' time) wait together, the 200 are all answered
    before half the burst is: about as much time each, 900 READs' worth here. (Served a piece
    each in turn, the burst had a slice per CONNECT, and was answered whole, or nearly, by
    then.)"""
    count, others = 3000, 200
    limits = ServerLimits(connections_per_peer=others, sessions_per_peer=others)
    loop = asyncio.get_running_loop()
    async with serving(limits=limits) as server:
        sock, session = await _connected(server.port, rcvbuf=1 << 20)  # room for its answers
        light = [
            socket.create_connection(
                ("127.0.0.1", server.port), timeout=2.0, source_address=("127.0.0.2", 0)
            )
            for _ in range(others)
        ]
        assert await until(lambda: server.connections.total == others + 1)
        # Sent while the loop does not run: all of it ready in the same turn (the rest of the
        # burst follows as the server reads).
        for other in light:
            other.sendall(b"CONNECT / RCTP/2.0\r\nCSeq: 1\r\n\r\n")
        burst = _reads(session, count)
        sock.setblocking(False)
        sent = sock.send(burst)
        sending = asyncio.ensure_future(loop.sock_sendall(sock, burst[sent:]))
        while not all(_has_data(other) for other in light):
            await asyncio.sleep(0)  # one turn of the loop: the burst's answers, seen at once
        answered = sock.recv(1 << 22, socket.MSG_PEEK).count(b"RCTP/2.0 ")
        assert answered < count // 2, answered
        for other in light:
            other.setblocking(True)
            assert other.recv(4096).startswith(b"RCTP/2.0 200 ")
            other.close()
        await sending
        sock.close()
