"""The reference server on asyncio: sockets and a clock around the sans-IO robot and sessions.

Nothing here decides anything about RCTP. A TCP connection becomes a `ServerSession`; the one UDP
socket (`datagrams`) hands each datagram to the session whose tag it carries (D-RCTP-28); the
HTTP port serves the robot's files (`files`). Each session and the robot have one timer handle on
the loop, moved only when their `get_timer()` changes. After anything reaches a session, `_flush`
sends what it has and closes the connection once it is finished.

A peer that does not read what it is sent cannot make the server buffer without bound: when a
connection's write buffer is full, the server stops reading from it until the buffer drains, and
resets it if it does not drain within the slow timeout (also once closed). Nor can one peer hold the
others up (D-RCTP-32, `limits`): connections are accepted a few a turn of the loop, and one beyond
its address's cap is closed as soon as it is accepted; one beyond the cap in all (RCTP's and the
files' counted together) closes a connection without a session to make room, or is closed itself
when every connection holds a session (`PeerCount`); a burst of pipelined requests is handed to its
session a slice per turn of the loop (reading the connection paused meanwhile); the connections'
work takes a budget of each turn, a peer address's connections a share of it, and what is left
waits, shared fairly among the addresses (`turns`); a connection with a large request under way
waits, unread, for one of a few places (a wait not counted against it as slowness); the data socket
is read several datagrams a wake-up, so that a flood of them does not crowd the sessions' out; and
an accept that fails for want of file descriptors is one line in the log now and then, not a
traceback each time.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import socket
import struct
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Any

from rcmlconf.rcml.model import RcmlDocument
from rcmlconf.rcml.url import DEFAULT_PORT, FILES_PORT_OFFSET, RctpUrl
from rcmlconf.rctp.datastream.endpoint import Address
from rcmlconf.rctp.datastream.packets import peek_tag
from rcmlconf.rctp.fields import DEFAULT_SESSION_TIMEOUT
from rcmlconf.reference.datagrams import DataSocket
from rcmlconf.reference.drivers import Driver
from rcmlconf.reference.faults import CONTROL_FAULTS, Fault, describe, rewrite_control
from rcmlconf.reference.server.faulty_robot import FaultyRobot
from rcmlconf.reference.server.faulty_session import FaultySession
from rcmlconf.reference.server.files import FileServer, robot_files
from rcmlconf.reference.server.limits import (
    ACCEPT_ERRNOS,
    ACCEPTS_A_TURN,
    LISTEN_QUEUE,
    PeerCount,
    Places,
    ServerLimits,
    connection_cap,
)
from rcmlconf.reference.server.robot import Robot
from rcmlconf.reference.server.session import ServerSession
from rcmlconf.reference.server.turns import Turns
from rcmlconf.reference.throttled import Throttled
from rcmlconf.reference.timers import BeatClock, LoopTimer

log = logging.getLogger("rcmlconf.server")

#: SO_LINGER on, for 0 s: close() resets the connection.
_LINGER_RESET = struct.pack("ii", 1, 0)
#: R-RCTP-23: how long a shutdown waits for the answers to its BYEs.
SHUTDOWN_WAIT = 5.0


@dataclass(frozen=True, slots=True)
class ServerSettings:
    host: str = "127.0.0.1"
    #: RCTP's TCP port, and the data stream's UDP port; 0 picks free ones.
    port: int = DEFAULT_PORT
    #: The files' HTTP port (D-RCTP-29); 0 picks a free one, None serves no files.
    http_port: int | None = DEFAULT_PORT + FILES_PORT_OFFSET
    seed: int = 0
    session_timeout: int = DEFAULT_SESSION_TIMEOUT
    #: Misbehaviours, none but to test a conformance harness (`reference.faults`).
    faults: frozenset[Fault] = frozenset()
    #: What one peer may take (D-RCTP-32).
    limits: ServerLimits = field(default_factory=ServerLimits)


class _Control(asyncio.Protocol):
    """One RCTP control connection."""

    def __init__(self, server: ReferenceServer) -> None:
        self.server = server
        self.session: ServerSession | None = None
        self.transport: asyncio.Transport | None = None
        self.timer: LoopTimer | None = None
        self.closing = False
        self.peer = "?"
        #: Input not yet handed to the session (a burst, a slice a turn), and why reading is
        #: paused: the backlog, the peer not taking its answers, or a large request waiting for
        #: a place (D-RCTP-32).
        self._backlog = bytearray()
        self._slicing = False
        self._write_paused = False
        self._waiting = False
        #: The connection is lost: its session's end is under way (`_lost`), nothing else.
        self._ended = False
        #: No CONNECT answered 200 on it yet: a full table may close it (D-RCTP-32).
        self._idle = True

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        assert isinstance(transport, asyncio.Transport)
        self.transport = transport
        peer = transport.get_extra_info("peername") or ("?", 0)
        server = self.server
        self.peer = peer[0]
        if not server.connections.admit(self.peer, self, server.loop.time()):
            # D-RCTP-32: beyond a cap there is no request to answer: closed at once.
            transport.abort()
            return
        loop = server.loop
        self.session = server.new_session((peer[0], peer[1]), loop.time())
        self.timer = LoopTimer(loop, self._timer_fired)
        self.timer.set(self.session.maintenance_timer())  # D-RCTP-32: from the first moment
        server.controls[self.session] = self

    def evict(self) -> None:
        """Closed to make room in a full table (D-RCTP-32, `PeerCount`): it holds no session,
        and what it was sent is dropped with it."""
        self.closing = True
        if self.transport is not None:
            _reset(self.transport)

    def data_received(self, data: bytes) -> None:
        if self.session is None or self.transport is None:
            return
        joins = bool(self._backlog) or self._waiting or self._slicing
        self._backlog += data
        if joins:  # still answering a burst, or waiting its turn: this joins it
            return
        self._slicing = True
        if not self.server.turns.run(self.peer, self._take_slice):
            self.transport.pause_reading()  # until its turn (`turns`): the kernel holds the rest

    def _take_slice(self) -> None:
        """Hand the session the backlog a piece at a time, for a slice's time (`ServerLimits`);
        if more is left, pause reading and come back in a next turn of the loop (after the
        other peers and the beats, `turns`)."""
        self._slicing = False
        session, transport = self.session, self.transport
        if session is None or transport is None or self._ended or self._write_paused:
            return  # resume_writing comes back for the rest
        if self._waiting:
            return  # _admitted comes back for it
        limits = self.server.settings.limits
        now = self.server.loop.time()
        until = time.perf_counter() + limits.slice_time
        room = True
        while self._backlog and room and not session.finished:
            piece = bytes(self._backlog[: limits.slice_bytes])
            del self._backlog[: limits.slice_bytes]
            session.receive_data(piece, now)
            room = self._has_room(session)
            if time.perf_counter() >= until:
                break
        if self._idle and session.id is not None:  # its CONNECT answered 200
            self._idle = False
            self.server.connections.seated(self.peer, self)
        self.server.flush(self)
        if not room:
            transport.pause_reading()
        elif self._backlog and not self.closing:
            transport.pause_reading()
            self._slicing = True
            self.server.turns.later(self.peer, self._take_slice)
        elif not self._write_paused and not self.closing:
            transport.resume_reading()

    def _has_room(self, session: ServerSession) -> bool:
        """Whether the request under way may take more input: a small one, or a large one with
        a place (D-RCTP-32); a large one without waits, unread, for its turn, a wait that does
        not count against its peer (`ServerSession.hold`)."""
        if session.conn.buffered <= self.server.settings.limits.large_bytes:
            self._leave_place()
            return True
        if self.server.large.take(self):
            return True
        self._waiting = True
        session.hold(self.server.loop.time())
        return False

    def _leave_place(self) -> None:
        for admitted in self.server.large.leave(self):
            admitted._admitted()

    def _admitted(self) -> None:
        """A large request's turn has come."""
        self._waiting = False
        if self.session is not None:
            self.session.go_on(self.server.loop.time())
        self._read_on()

    def _read_on(self) -> None:
        """Unless something else still holds reading back: the rest of the backlog in a next
        turn of the loop, or reading again."""
        transport = self.transport
        if transport is None or self._ended or self.closing or self._waiting:
            return
        if self._write_paused:
            return
        if self._backlog:
            if not self._slicing:
                self._slicing = True
                self.server.turns.later(self.peer, self._take_slice)
        else:
            transport.resume_reading()

    def eof_received(self) -> bool:
        """The peer sends no more (a half-close). asyncio tells so only while it reads, and
        reading is paused while a burst's slices wait (`_take_slice`): what came before has
        been answered in slices already. The session ends; asyncio closes the connection once
        its last answers have left, within D-RCTP-32's time (`ReferenceServer._flush_one`)."""
        session = self.session
        self._leave_place()
        if session is not None and not session.finished:
            session.receive_data(b"", self.server.loop.time())
            self.server.flush(self)
        return False

    def connection_lost(self, exc: Exception | None) -> None:
        # The connection is gone: its descriptor no longer counts. The session's end waits its
        # peer's turn (`turns`), so that a flood of resets is not one long turn of the loop.
        _uncycle(self.transport)
        if self.session is not None and not self._ended:
            self._ended = True
            self.server.connections.leave(self.peer, self)
            self.server.turns.run(self.peer, self._lost)

    def _lost(self) -> None:
        """The connection broke, or its close is over: the session ends, if it has not, and
        everything of the connection is let go."""
        session = self.session
        assert session is not None
        self._waiting = False
        self._leave_place()
        if not session.finished:
            session.receive_data(b"", self.server.loop.time())
            self.server.flush(self)
        self._backlog.clear()
        if self.timer is not None:
            self.timer.set(None)
            # The timer's callback is this connection's method: without the timer, the connection
            # and its session are freed when the last reference goes, not at the collector's next
            # pass (a 4 MiB request's buffers with them, D-RCTP-32).
            self.timer = None
        self.server.beats.set(self, None)
        self.server.controls.pop(session, None)

    def pause_writing(self) -> None:
        # The peer does not take its answers: reading waits (TCP then holds the peer), and
        # the peer has D-RCTP-32's slow timeout to take some again.
        self._write_paused = True
        if self.transport is not None:
            self.transport.pause_reading()
        if self.session is not None and self.timer is not None:
            self.session.stalled(self.server.loop.time())
            self.timer.set(self.session.maintenance_timer())

    def resume_writing(self) -> None:
        self._write_paused = False
        if self.session is not None and not self.closing:  # a close's answers stay timed
            self.session.stalled(None)
        self._read_on()

    def _timer_fired(self) -> None:
        if self.session is not None:
            self.server.turns.run(self.peer, self._timer_work)

    def _timer_work(self) -> None:
        session, transport = self.session, self.transport
        if session is None or transport is None or self._ended:
            return
        session.handle_timer(self.server.loop.time())
        if session.reset:  # its answers were not taken: they never would be (D-RCTP-32)
            self.closing = True
            _reset(transport)
        self.server.flush(self)


def _uncycle(transport: asyncio.Transport | None) -> None:
    """asyncio's socket transport holds a bound method of its own (`_read_ready_cb`, CPython 3.11
    to 3.13): a reference cycle, so a closed one, its socket and buffers wait for the collector,
    and under a flood of connections enough of them live long enough to reach its oldest
    generation (`collector`). Once the connection is lost the transport reads no more: the cycle
    is broken, and the last reference frees it."""
    if getattr(transport, "_read_ready_cb", None) is not None:
        setattr(transport, "_read_ready_cb", None)  # noqa: B010 (asyncio's own, untyped)


def _reset(transport: asyncio.Transport) -> None:
    """Close with a reset: what waits to be sent is dropped, by asyncio and by the kernel too
    (a socket closed with data unsent would otherwise stay, an orphan, sending it)."""
    sock = transport.get_extra_info("socket")
    if sock is not None:
        with contextlib.suppress(OSError):
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, _LINGER_RESET)
    transport.abort()


class _Data:
    """What comes on the data stream's one UDP socket, shared by every session (D-RCTP-28)."""

    def __init__(self, server: ReferenceServer) -> None:
        self.server = server
        self.unclaimed = 0

    def datagram_received(self, data: bytes, addr: Address) -> None:
        tag = peek_tag(data)
        session = self.server.robot.by_tag.get(tag) if tag is not None else None
        control = self.server.controls.get(session) if session is not None else None
        if session is None or control is None:
            self.unclaimed += 1  # R-RCTP-42: no session's tag, dropped unanswered
            return
        session.receive_datagram(data, addr, self.server.loop.time())
        self.server.flush(control)


def _paced(server: asyncio.Server) -> asyncio.Server:
    """`server`, told to accept ACCEPTS_A_TURN connections a turn of the loop (D-RCTP-32),
    which asyncio also made its sockets' listen backlog: the kernel's queue is made LISTEN_QUEUE
    long again (listen() of a listening socket sets its backlog anew, on any of its
    descriptors)."""
    for listening in server.sockets:
        with socket.fromfd(listening.fileno(), listening.family, listening.type) as same:
            same.listen(LISTEN_QUEUE)
    return server


class ReferenceServer:
    """One robot on RCTP/2.0, its data stream, and its files over HTTP."""

    def __init__(
        self, rcml: Path, model: RcmlDocument, driver: Driver, settings: ServerSettings
    ) -> None:
        self.rcml = rcml
        self.model = model
        self.driver = driver
        self.settings = settings
        #: The faults that rewrite what the control connections write (`rewrite_control`).
        self._control_faults = settings.faults & CONTROL_FAULTS
        #: Every open control connection, by its session.
        self.controls: dict[ServerSession, _Control] = {}
        self._loop: asyncio.AbstractEventLoop | None = None
        self._robot: Robot[ServerSession] | None = None
        self._tcp: asyncio.Server | None = None
        self._http: asyncio.Server | None = None
        self._udp: DataSocket | None = None
        self.data = _Data(self)
        self._robot_timer: LoopTimer | None = None
        self._beats: BeatClock[_Control] | None = None
        self._turns: Turns | None = None
        self.files: FileServer | None = None
        limits = settings.limits
        #: Open connections, RCTP's and the files', against D-RCTP-32's caps.
        self.connections = PeerCount(
            connection_cap(limits.connections), limits.connections_per_peer
        )
        #: The connections with a large request under way (D-RCTP-32).
        self.large: Places[_Control] = Places(limits.large_requests)
        self._accept_failed = Throttled(log, "cannot accept connections")
        self._handler: Any = None

    @property
    def loop(self) -> asyncio.AbstractEventLoop:
        assert self._loop is not None, "start() first"
        return self._loop

    @property
    def beats(self) -> BeatClock[_Control]:
        """Every session's stream beats, on one clock (`BeatClock`)."""
        assert self._beats is not None, "start() first"
        return self._beats

    @property
    def turns(self) -> Turns:
        """The connections' work, a budget a turn, shared among the peers (`turns`)."""
        assert self._turns is not None, "start() first"
        return self._turns

    @property
    def robot(self) -> Robot[ServerSession]:
        assert self._robot is not None, "start() first"
        return self._robot

    def new_session(self, peer: Address, now: float) -> ServerSession:
        """The session of a new control connection: a faulty one when the server has faults."""
        if self.settings.faults:
            return FaultySession(self.settings.faults, self.robot, peer, now)
        return ServerSession(self.robot, peer, now)

    # -- life --------------------------------------------------------------------------------

    async def start(self) -> None:
        """Listen: RCTP on TCP, the data stream on UDP, the files on HTTP. If one cannot be had
        (a port in use), what was opened before it is closed again and the OSError raised."""
        if self.settings.faults:
            log.warning(
                "running with faults, to test a conformance harness: %s",
                describe(self.settings.faults),
            )
        try:
            await self._listen()
        except BaseException:
            await self._close_listeners()
            raise

    async def _listen(self) -> None:
        loop = self._loop = asyncio.get_running_loop()
        settings = self.settings
        self._handler = loop.get_exception_handler()
        loop.set_exception_handler(self._loop_exception)
        self._turns = Turns(loop, settings.limits.turn_budget, settings.limits.peer_share)
        self._tcp = _paced(
            await loop.create_server(
                lambda: _Control(self),
                settings.host,
                settings.port,
                reuse_address=True,
                backlog=ACCEPTS_A_TURN,
            )
        )
        port = self.port
        udp = await DataSocket.bind(
            settings.host, port if settings.port else 0, self.data.datagram_received, log
        )
        self._udp = udp
        # With faults, the robot and its sessions are the faulty subclasses (`reference.faults`).
        make: Callable[..., Robot[ServerSession]] = (
            partial(FaultyRobot, settings.faults) if settings.faults else Robot
        )
        self._robot = make(
            self.model,
            self.driver,
            loop.time(),
            seed=settings.seed,
            data_port=udp.port,
            session_timeout=settings.session_timeout,
            unix_offset=time.time() - loop.time(),
            limits=settings.limits,
        )
        self._beats = BeatClock(loop, self._beat)
        self._robot_timer = LoopTimer(loop, self._tick)
        self._robot_timer.set(self._robot.get_timer())
        if settings.http_port is not None:
            self.files = FileServer(
                self.model.title or self.rcml.name,
                robot_files(self.rcml, self.model),
                settings.limits,
                self.connections,  # D-RCTP-32: one cap over the process's connections
            )
            self._http = _paced(
                await asyncio.start_server(
                    self.files.handle,
                    settings.host,
                    settings.http_port,
                    reuse_address=True,
                    backlog=ACCEPTS_A_TURN,
                )
            )

    @property
    def port(self) -> int:
        assert self._tcp is not None, "start() first"
        return int(self._tcp.sockets[0].getsockname()[1])

    @property
    def data_port(self) -> int:
        return self.robot.data_port

    @property
    def http_port(self) -> int | None:
        return int(self._http.sockets[0].getsockname()[1]) if self._http is not None else None

    @property
    def url(self) -> str:
        """The robot's RCTP URL as served (D-RCML-17's `site`, with the port in use)."""
        return str(RctpUrl(self.settings.host, self.port, self.robot.site_path))

    async def stop(self) -> None:
        """Graceful shutdown: BYE to every session (`Reason: shutdown`), then close."""
        if self._tcp is not None:
            self._tcp.close()
        if self._http is not None:
            self._http.close()
        now = self.loop.time()
        for session, control in tuple(self.controls.items()):
            session.shut_down(now)
            self.flush(control)
        deadline = now + SHUTDOWN_WAIT + 0.5
        while self.controls and self.loop.time() < deadline:
            await asyncio.sleep(0.01)
        for control in tuple(self.controls.values()):
            if control.transport is not None:
                control.transport.abort()
        await self._close_listeners()

    def _loop_exception(self, loop: asyncio.AbstractEventLoop, context: dict[str, Any]) -> None:
        """An accept that failed for want of descriptors or memory: asyncio tries again a
        second later by itself, and the log says so once an interval, in a line, with how many
        connections are open. Anything else goes to the handler there was."""
        error = context.get("exception")
        if isinstance(error, OSError) and error.errno in ACCEPT_ERRNOS:
            detail = f"{error.strerror} ({self.connections.total} connections open)"
            self._accept_failed.happened(loop.time(), detail)
            return
        if self._handler is not None:
            self._handler(loop, context)
        else:
            loop.default_exception_handler(context)

    async def _close_listeners(self) -> None:
        if self._loop is not None and self._loop.get_exception_handler() == self._loop_exception:
            self._loop.set_exception_handler(self._handler)
        if self._robot_timer is not None:
            self._robot_timer.set(None)
        if self._udp is not None:
            self._udp.close()
        for server in (self._tcp, self._http):
            if server is not None:
                server.close()
                await server.wait_closed()

    # -- moving bytes ------------------------------------------------------------------------

    def flush(self, control: _Control) -> None:
        """Send what the session has, and what other sessions were given by its doing."""
        self._flush_one(control)
        for session in self.robot.touched():
            other = self.controls.get(session)
            if other is not None:
                self._flush_one(other)

    def _flush_one(self, control: _Control) -> None:
        session, transport = control.session, control.transport
        if session is None or transport is None:
            return
        data = session.data_to_send()
        if data and self._control_faults:  # fault: those of faults.CONTROL_FAULTS
            data = rewrite_control(data, self._control_faults)
        if data and not transport.is_closing():
            transport.write(data)
        datagrams, peer = session.datagrams_to_send(self.loop.time())
        if datagrams and peer is not None and self._udp is not None:
            for datagram in datagrams:
                self._udp.sendto(datagram, peer)
        if session.finished and not control.closing:
            control.closing = True
            transport.close()  # after what is written has left: within the slow timeout
            if transport.get_write_buffer_size():
                session.stalled(self.loop.time())
        if control.timer is not None:
            control.timer.set(session.maintenance_timer())
        self.beats.set(control, None if control.closing else session.beat_timer())

    def _beat(self, controls: list[_Control]) -> None:
        """The sessions whose streams are due now: their DATA, and nothing else."""
        now = self.loop.time()
        udp = self._udp
        for control in controls:
            session = control.session
            if session is None or control.closing or udp is None:
                continue
            session.beat(now)
            datagrams, peer = session.datagrams_to_send(now)
            if peer is not None:
                for datagram in datagrams:
                    udp.sendto(datagram, peer)
            self.beats.set(control, session.beat_timer())

    def _tick(self) -> None:
        robot = self.robot
        robot.handle_timer(self.loop.time())
        for session in robot.touched():
            control = self.controls.get(session)
            if control is not None:
                self._flush_one(control)
        assert self._robot_timer is not None
        self._robot_timer.set(robot.get_timer())
