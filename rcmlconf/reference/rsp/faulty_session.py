"""The RSP robot endpoint of a faulty reference robot (`reference.faults.ROBOT_FAULTS`).

RSP's rules live in the core's `RobotEndpoint`, which the reference robot and the experiments
share: the faults are not put there. A reference robot with faults makes
its endpoint of this subclass instead (`ReferenceRobot`), which breaks the rules as a robot's own
code would, each fault at the method where such a bug would sit. Without faults the robot makes
the core's `RobotEndpoint`, untouched: its beat pays nothing for them.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

from rcmlconf.rctp.datastream.order import Arrival, SequenceTracker
from rcmlconf.reference.faults import Fault, loose_model
from rcmlconf.rsp.codec import (
    CLEAR_BUFFER,
    ByeReason,
    Header,
    Hello,
    Item,
    MapBody,
    PacketType,
    RefusedReason,
    codec_for,
)
from rcmlconf.rsp.codec.bodies import Body
from rcmlconf.rsp.codec.header import LAST_AT, SESSION_AT, TYPE_AT
from rcmlconf.rsp.model import Device
from rcmlconf.rsp.reliable import Occurrence, ReceivedIds, ReliableSender
from rcmlconf.rsp.session import events
from rcmlconf.rsp.session.robot import Address, RobotEndpoint, RobotSession
from rcmlconf.rsp.session.wire import SENT_TO_ROBOT, SessionWire, drop_unsent
from rcmlconf.values import Value

_HELLO = bytes([PacketType.HELLO])


class FaultyRobotEndpoint(RobotEndpoint):
    __slots__ = ("faults",)

    def __init__(self, faults: frozenset[Fault], *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.faults = faults
        if Fault.PAYLOAD_SIZE_UNCHECKED in faults:
            # fault: payload-size-unchecked: packets read as a model with no size limit would be
            self.codec = codec_for(loose_model(self.model))

    @property
    def free_buffers(self) -> int:
        if Fault.FREE_BUFFERS_STUCK in self.faults:  # fault: free-buffers-stuck
            return self.model.command_buffers
        return super().free_buffers

    # -- receiving -----------------------------------------------------------------------------

    def _receive(self, data: bytes, peer: Address, now: float) -> None:
        session = self.session
        # The core reads a packet as the session's when one is open, the packet is no HELLO and
        # it comes from the session's address; any other goes the way of a HELLO.
        if session is not None and data[TYPE_AT : TYPE_AT + 1] != _HELLO:
            faults = self.faults
            if Fault.SOURCE_UNCHECKED in faults:  # fault: source-unchecked
                peer = session.peer  # from anywhere, a packet is the session's
            if peer == session.peer and faults & _READ_FAULTS:
                # The core drops a packet of a type not sent to a robot before reading anything
                # of it: so do the faults of reading, or they would change what comes next.
                drop_unsent(data, SENT_TO_ROBOT, "a robot")
                data = self._faulty_read(session, data)
        super()._receive(data, peer, now)

    def _faulty_read(self, session: RobotSession, data: bytes) -> bytes:
        """What the faults of reading a session's packet make of it before it is read."""
        if Fault.REPLAY_WINDOW_OFF in self.faults:  # fault: replay-window-off
            session.wire.tracker = SequenceTracker()  # every packet is the first, so newer
        if Fault.SESSION_ID_UNCHECKED in self.faults and len(data) >= LAST_AT:
            # fault: session-id-unchecked: whatever the packet names, it is the session's
            session_id = session.wire.session_id.to_bytes(LAST_AT - SESSION_AT, "big")
            data = data[:SESSION_AT] + session_id + data[LAST_AT:]
        return data

    def _welcome_again(self, session: RobotSession) -> None:
        if Fault.NO_RETRANSMISSION not in self.faults:  # fault: no-retransmission
            super()._welcome_again(session)

    def _open(self, wire: SessionWire, hello: Hello, peer: Address, now: float) -> None:
        super()._open(wire, hello, peer, now)
        if Fault.NO_RETRANSMISSION in self.faults:  # fault: no-retransmission
            assert self.session is not None
            self._memory_events = _SentOnce(self._ids, self.session.beat.period)

    def _refuse(self, header: Header, reason: RefusedReason, peer: Address, now: float) -> None:
        if Fault.REFUSED_OWN_MODEL in self.faults:  # fault: refused-own-model
            header = header._replace(model_id=self.model.model_id)
        super()._refuse(header, reason, peer, now)

    def _downlink(
        self,
        session: RobotSession,
        header: Header,
        body: MapBody,
        arrival: Arrival,
        now: float,
    ) -> None:
        faults = self.faults
        if Fault.CLEAR_BUFFER_IGNORED in faults:  # fault: clear-buffer-ignored
            header = header._replace(buffer=header.buffer & ~CLEAR_BUFFER)
        super()._downlink(session, header, body, arrival, now)
        # After the core, which sets what is requested from a newer DOWNLINK's flags.
        if arrival is Arrival.NEWER and Fault.UNREQUESTED_REPORTED in faults:
            session.requested |= self._reported  # fault: unrequested-reported

    def _occurrence(
        self, session: RobotSession, position: int, ident: int, values: Mapping[str, Value]
    ) -> bool:
        faults = self.faults
        if Fault.DUPLICATES_TAKEN in faults:  # fault: duplicates-taken: every occurrence is new
            session.commands = ReceivedIds(self._ids)
        elif Fault.REPEAT_NOT_ACKED in faults and not session.commands.is_new(position, ident):
            return False  # fault: repeat-not-acked: seen before, not acknowledged again
        return super()._occurrence(session, position, ident, values)

    # -- sending and silence -------------------------------------------------------------------

    def _send(self, session: RobotSession, kind: PacketType, body: Body, now: float) -> None:
        faults = self.faults
        if kind is PacketType.ACK and Fault.ACK_NEXT_ID in faults:  # fault: ack-next-id
            assert isinstance(body, MapBody)
            body = MapBody(tuple(Item(i.device, _next(i.id, self._ids)) for i in body.items))
        super()._send(session, kind, body, now)
        if Fault.SEQUENCE_FROZEN in faults:  # fault: sequence-frozen
            session.wire.sent -= 1

    def _time_out(self, now: float) -> None:
        if Fault.SILENT_TIMEOUT in self.faults:  # fault: silent-timeout
            self._end(events.SessionClosed(ByeReason.TIMEOUT, by_peer=False))
            return
        super()._time_out(now)

    def _stop_on_loss(self, session: RobotSession) -> None:
        if Fault.NO_STOP_ON_LOSS not in self.faults:  # fault: no-stop-on-loss
            super()._stop_on_loss(session)


#: The faults of reading a session's packet (`_faulty_read`).
_READ_FAULTS = frozenset({Fault.REPLAY_WINDOW_OFF, Fault.SESSION_ID_UNCHECKED})


class _SentOnce(ReliableSender):
    """Memory events sent once and never again (fault: no-retransmission)."""

    __slots__ = ()

    def due(self, now: float, may_start: Callable[[Device], bool]) -> list[Occurrence]:
        return [o for o in super().due(now, may_start) if o.last_sent is None]


def _next(ident: int | None, space: int) -> int:
    """The ID after `ident`: TCP's next expected (fault: ack-next-id)."""
    assert ident is not None
    return (ident + 1) % space
