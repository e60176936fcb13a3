"""One robot served by the reference server, without I/O: what all its sessions share.

The robot holds the model and the driver that owns the values. It holds the privilege table
(D-RCTP-16), the sessions and their data-stream tags. It knows which session watches which event
access (D-RCTP-27). Time is a value: the adapter calls `handle_timer(now)` at `get_timer()`.
Then the driver moves on, and the robot hands the changes to the sessions that watch them.
"""

from __future__ import annotations

import os
from collections import Counter
from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import Generic, Protocol, TypeVar

from rcmlconf.rcml.model import AccessNode, DataNode, RcmlDocument
from rcmlconf.rctp.bodies import ValuesCodec
from rcmlconf.rctp.datastream.endpoint import Address
from rcmlconf.rctp.datastream.flow import Direction
from rcmlconf.rctp.datastream.values import stream_codec
from rcmlconf.rctp.fields import DEFAULT_SESSION_TIMEOUT
from rcmlconf.reference.drivers import Driver
from rcmlconf.reference.server.limits import DEFAULT_LIMITS, ServerLimits
from rcmlconf.reference.server.privileges import Privileges
from rcmlconf.values import Value

#: D-RCTP-27: how often the reference server moves the driver on and looks for changes.
TICK = 0.01
#: READ and WRITE codecs kept at most (`Robot.codec`).
_CODECS_KEPT = 4096
#: 16 random bytes make a session ID of 22 characters (D-RCTP-11: unguessable, 8 to 64).
_ID_BYTES = 16


class Watcher(Protocol):
    """What the robot needs of a session (`session.ServerSession`): the peer address that counts
    against D-RCTP-32's cap, and to be handed the changes of the event accesses it watches."""

    @property
    def peer(self) -> Address: ...

    def note_changes(self, access: str, names: Iterable[str], now: float) -> None: ...


#: The sessions a robot holds: the robot hands them back (`touched`, `by_tag`) as they are.
S = TypeVar("S", bound=Watcher)


class Robot(Generic[S]):
    def __init__(
        self,
        model: RcmlDocument,
        driver: Driver,
        now: float,
        *,
        seed: int = 0,
        data_port: int = 0,
        session_timeout: int = DEFAULT_SESSION_TIMEOUT,
        unix_offset: float = 0.0,
        random_bytes: Callable[[int], bytes] = os.urandom,
        limits: ServerLimits = DEFAULT_LIMITS,
    ) -> None:
        """`data_port` is the UDP port of every session's data stream (D-RCTP-28).
        `unix_offset` turns `now` into Unix time, for data-stream timestamps. `limits` say
        what one peer may take (D-RCTP-32)."""
        self.model = model
        self.site_path = model.site.path or "/"
        self.driver = driver
        self.data_port = data_port
        self.session_timeout = session_timeout
        self.unix_offset = unix_offset
        self.random_bytes = random_bytes
        self.privileges = Privileges()
        #: Open sessions by ID, and by their data-stream tag (the adapter's demultiplexer).
        self.sessions: dict[str, S] = {}
        self.limits = limits
        #: Open sessions by peer address (D-RCTP-32's cap).
        self._per_peer: Counter[str] = Counter()
        self.by_tag: dict[int, S] = {}
        #: Event access path -> the sessions where it plays.
        self._watchers: dict[str, set[S]] = {}
        #: Encoded DATA bodies of this tick, shared by every session that streams the access.
        self._bodies: dict[tuple[str, Direction], bytes] = {}
        self._stream_codecs: dict[tuple[str, Direction], ValuesCodec[DataNode]] = {}
        self._codecs: dict[tuple[str, tuple[str, ...]], ValuesCodec[DataNode]] = {}
        #: Sessions given something to send by another's doing: the adapter flushes them.
        self._touched: set[S] = set()
        self._next_tick = now
        driver.start(model, now, seed)

    # -- values ------------------------------------------------------------------------------

    def values(self, nodes: Iterable[DataNode]) -> dict[str, Value]:
        """The current values of some data nodes, by name."""
        current = self.driver.values()
        return {node.name: current[node.path] for node in nodes}

    def body(self, access: AccessNode, direction: Direction) -> bytes:
        """A stream's DATA body now (D-RCTP-20), encoded once per tick for all sessions."""
        key = (access.path, direction)
        body = self._bodies.get(key)
        if body is None:
            codec = self._stream_codecs.get(key)
            if codec is None:
                codec = self._stream_codecs[key] = self._stream_codec(access, direction)
            body = self._bodies[key] = codec.encode(self.values(codec.nodes))
        return body

    def _stream_codec(self, access: AccessNode, direction: Direction) -> ValuesCodec[DataNode]:
        """The codec of a stream's DATA in one direction (D-RCTP-20)."""
        return stream_codec(access, direction)

    def codec(self, where: str, nodes: Sequence[DataNode]) -> ValuesCodec[DataNode]:
        """The codec of READ and WRITE bodies of `nodes` of the access or node `where`.
        Each is made once, since clients ask for the same few again and again. The memory is
        bounded, since a client may name any subset of an event access's nodes."""
        key = (where, tuple(node.name for node in nodes))
        codec = self._codecs.get(key)
        if codec is None:
            if len(self._codecs) >= _CODECS_KEPT:
                self._codecs.clear()
            codec = self._codecs[key] = self._body_codec(where, nodes)
        return codec

    def _body_codec(self, where: str, nodes: Sequence[DataNode]) -> ValuesCodec[DataNode]:
        """The codec of READ and WRITE bodies of `nodes`, in canonical order (R-RCTP-28)."""
        return ValuesCodec(nodes, where, "R-RCTP-28")

    def command(self, by: S, values: Mapping[str, Value], now: float) -> None:
        """Values a session wrote, checked already, applied together (R-RCTP-29)."""
        self._changed(self.driver.command(values, now), by, now)

    # -- sessions ----------------------------------------------------------------------------

    def open_session(self, session: S) -> str | None:
        """A new session's ID, or None when its peer address has as many as it may
        (D-RCTP-32: the CONNECT is answered 503)."""
        peer = session.peer[0]
        if self._per_peer[peer] >= self.limits.sessions_per_peer:
            return None
        self._per_peer[peer] += 1
        while True:
            session_id = self.random_bytes(_ID_BYTES).hex()
            if session_id not in self.sessions:
                self.sessions[session_id] = session
                return session_id

    def new_tag(self, session: S) -> int:
        """An unguessable data-stream tag no other session has (D-RCTP-18)."""
        while True:
            tag = int.from_bytes(self.random_bytes(4), "big")
            if tag and tag not in self.by_tag:
                self.by_tag[tag] = session
                return tag

    def close_session(self, session: S, session_id: str | None, tag: int | None) -> None:
        """The session is over: its privileges go (R-RCTP-36), its watches and tag too."""
        if session_id is not None and self.sessions.pop(session_id, None) is not None:
            peer = session.peer[0]
            self._per_peer[peer] -= 1
            if self._per_peer[peer] <= 0:
                del self._per_peer[peer]
            self._session_ended(session_id)
        if tag is not None:
            self.by_tag.pop(tag, None)
        for watchers in self._watchers.values():
            watchers.discard(session)

    def _session_ended(self, session_id: str) -> None:
        """R-RCTP-36: a session's privileges end with it."""
        self.privileges.release_all(session_id)

    def watch(self, session: S, access: str) -> None:
        self._watchers.setdefault(access, set()).add(session)

    def unwatch(self, session: S, access: str) -> None:
        self._watchers.get(access, set()).discard(session)

    # -- time --------------------------------------------------------------------------------

    def get_timer(self) -> float:
        return self._next_tick

    def handle_timer(self, now: float) -> None:
        if now < self._next_tick:
            return
        # Keep the beat; after a stall, start again from now rather than run to catch up.
        self._next_tick += TICK
        if self._next_tick <= now:
            self._next_tick = now + TICK
        self._changed(self.driver.advance(now), None, now)

    def _changed(self, paths: Iterable[str], by: S | None, now: float) -> None:
        """Hand changes to the sessions watching them, except the one that made them (R-RCTP-54)."""
        by_access: dict[str, list[str]] = {}
        for path in paths:
            access, _, name = path.rpartition("/")
            by_access.setdefault(access, []).append(name)
        if not by_access:
            return
        self._bodies.clear()
        for access, names in by_access.items():
            for session in tuple(self._watchers.get(access, ())):
                if session is not by:
                    session.note_changes(access, names, now)
                    self._touched.add(session)

    def touched(self) -> set[S]:
        """The sessions that may have something to send since the last call."""
        touched, self._touched = self._touched, set()
        return touched
