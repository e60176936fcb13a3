"""The data stream of a faulty reference server (`reference.faults.STREAM_FAULTS`).

The data stream's rules live in the core's `Endpoint`, which the client and the harness share.
The faults are not put there. A faulty session with one of these faults makes its endpoint of
this subclass instead (`FaultySession._new_endpoint`). It breaks the rules as a server's own
data-stream code would. Without these faults the session makes the core's `Endpoint`.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

from rcmlconf.errors import ProtocolError
from rcmlconf.rcml.model import AccessNode
from rcmlconf.rctp.datastream.endpoint import Address, Endpoint, Stream
from rcmlconf.rctp.datastream.events import PacketDropped
from rcmlconf.rctp.datastream.flow import FlowMessage, HeartbeatAck, IntervalSet, IntervalSetAck
from rcmlconf.rctp.datastream.order import SequenceTracker
from rcmlconf.rctp.datastream.packets import EncodedPayload, UnknownPayload, pull_packet
from rcmlconf.reference.faults import LENIENT_VALUES, Fault, faulty_stream_codec


class FaultyEndpoint(Endpoint):
    def __init__(self, faults: frozenset[Fault], *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.faults = faults

    def add_stream(self, stream_id: int, access: AccessNode, mode: str) -> Stream:
        stream = super().add_stream(stream_id, access, mode)
        if self.faults & LENIENT_VALUES:  # fault: bool-nonzero-true, string-size-unchecked
            stream.codecs = {
                d: faulty_stream_codec(c, self.faults) for d, c in stream.codecs.items()
            }
        return stream

    def receive_datagram(self, data: bytes, addr: Address, now: float) -> bool:
        faults = self.faults
        if Fault.STALE_DATA_APPLIED in faults:  # fault: stale-data-applied
            self.sequences = SequenceTracker()  # every packet is the first, so newer
        if Fault.UNKNOWN_PAYLOAD_DROPS in faults and _unknown_payload(data):
            self._events.append(PacketDropped("a payload of an unknown type", "R-RCTP-51"))
            return False  # fault: unknown-payload-drops
        return super().receive_datagram(data, addr, now)

    def _answer(self, stream_id: int, request: FlowMessage, now: float) -> None:
        faults = self.faults
        if Fault.FLOW_ANSWERS_FORGOTTEN in faults:  # fault: flow-answers-forgotten
            self._answers.clear()
        if Fault.SHORT_INTERVAL_ACCEPTED in faults and isinstance(request, IntervalSet):
            # fault: short-interval-accepted: any interval of this end's direction is taken
            stream = self.streams.get(stream_id)
            direction = request.direction
            if stream is not None and direction is self.sends and direction in stream.codecs:
                stream.intervals[direction] = max(request.interval, 1)
                ack = IntervalSetAck(request.request_id, direction, stream.intervals[direction])
                self._queue(stream_id, ack)
                return
        super()._answer(stream_id, request, now)

    def _queue(self, stream: int, flow: FlowMessage) -> None:
        if Fault.HEARTBEAT_NO_T1 in self.faults and isinstance(flow, HeartbeatAck):
            flow = replace(flow, t1=flow.t2)  # fault: heartbeat-no-t1
        super()._queue(stream, flow)

    def _packet(self, payloads: list[EncodedPayload], stamp: int) -> None:
        super()._packet(payloads, stamp)
        if Fault.SEQUENCE_SKIPS in self.faults:  # fault: sequence-skips
            self._sequence = (self._sequence + 1) & 0xFFFF


def _unknown_payload(data: bytes) -> bool:
    try:
        packet = pull_packet(data)
    except ProtocolError:
        return False
    return any(isinstance(payload, UnknownPayload) for payload in packet.payloads)
