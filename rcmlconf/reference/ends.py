"""What the server's and the client's sessions share: one end of an RCTP/2.0 session, sans I/O.

An end is a control connection (`rctp.connection`) and, once a stream is set up, a data stream
(`rctp.datastream.endpoint`). Bytes, datagrams and timers go in here; what they mean is the
subclass's `_process`, and which DATA bodies are due to leave its `_bodies`.
"""

from __future__ import annotations

from abc import ABC, abstractmethod

from rcmlconf.rctp.connection import Connection
from rcmlconf.rctp.datastream.endpoint import Address, Endpoint
from rcmlconf.rctp.states import Role


class SessionEnd(ABC):
    def __init__(self, role: Role, now: float) -> None:
        self.conn = Connection(role, now)
        self.endpoint: Endpoint | None = None

    @abstractmethod
    def _process(self, now: float) -> None:
        """Take the events of the connection and of the data stream."""

    @abstractmethod
    def _bodies(self, due: tuple[int, ...]) -> dict[int, bytes]:
        """The DATA bodies to send now, of the due streams this end has values for."""

    # -- input -------------------------------------------------------------------------------

    def receive_data(self, data: bytes, now: float) -> None:
        """Bytes from the control connection; b"" when the peer closed it."""
        self.conn.receive_data(data, now)
        self._process(now)

    def receive_datagram(self, data: bytes, addr: Address, now: float) -> None:
        if self.endpoint is None:
            return
        ours = self.endpoint.receive_datagram(data, addr, now)
        if ours and self.conn.role is Role.SERVER:
            self.conn.note_activity(now)  # D-RCTP-11: a client's packets keep its session
        self._process(now)

    def get_timer(self) -> float | None:
        """When `handle_timer` should next be called (the earlier of the two below)."""
        beat, other = self.beat_timer(), self.maintenance_timer()
        if beat is None or (other is not None and other < beat):
            return other
        return beat

    def beat_timer(self) -> float | None:
        """When a stream is next due to send: `beat` does it."""
        return self.endpoint.send_timer() if self.endpoint is not None else None

    def maintenance_timer(self) -> float | None:
        """When anything else is due: the session's and the data stream's timers."""
        # Asked after every packet of every session: no lists, no generators.
        timer = self.conn.get_timer()
        if self.endpoint is not None:
            stream_timer = self.endpoint.maintenance_timer()
            if stream_timer is not None and (timer is None or stream_timer < timer):
                timer = stream_timer
        return timer

    def beat(self, now: float) -> None:
        """Send the DATA of the streams due, and nothing else: what most timers are for, kept
        short for a server with hundreds of sessions. Raises no events."""
        endpoint = self.endpoint
        if endpoint is None:
            return
        due = endpoint.due(now)
        if due:
            bodies = self._bodies(due)
            if bodies:
                endpoint.send_data(bodies, now)
            if len(bodies) < len(due):
                endpoint.skip([stream for stream in due if stream not in bodies], now)

    def handle_timer(self, now: float) -> None:
        """Everything due: the connection's timers, the data stream's, and the beat."""
        self.conn.handle_timer(now)
        if self.endpoint is not None:
            self.endpoint.handle_timer(now)
        self.beat(now)
        self._process(now)

    # -- output ------------------------------------------------------------------------------

    def data_to_send(self) -> bytes:
        return self.conn.data_to_send()

    def datagrams_to_send(self, now: float) -> tuple[list[bytes], Address | None]:
        """The datagrams waiting, and where they go (the session's peer, R-RCTP-56)."""
        if self.endpoint is None:
            return [], None
        return self.endpoint.datagrams_to_send(now), self.endpoint.peer
