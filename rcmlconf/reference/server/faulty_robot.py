"""The robot of a faulty reference server (`reference.faults`).

The rules a robot keeps for all its sessions live in the core's `Robot`. The faults are not put
there. A server with faults makes its robot of this subclass instead (`ReferenceServer`). Each
fault breaks one rule, in the method where such a bug would sit. The robot's privilege table is
faulty too (`FaultyPrivileges`).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any

from rcmlconf.rcml.model import AccessNode, DataNode
from rcmlconf.rctp.bodies import ValuesCodec
from rcmlconf.rctp.datastream.flow import Direction
from rcmlconf.reference.faults import LENIENT_VALUES, Fault, faulty_codec, faulty_stream_codec
from rcmlconf.reference.server.faulty_privileges import FaultyPrivileges
from rcmlconf.reference.server.robot import Robot, S


class FaultyRobot(Robot[S]):
    def __init__(self, faults: frozenset[Fault], *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.faults = faults
        self.privileges = FaultyPrivileges(faults)

    def _stream_codec(self, access: AccessNode, direction: Direction) -> ValuesCodec[DataNode]:
        codec = super()._stream_codec(access, direction)
        if self.faults & LENIENT_VALUES:
            # fault: bool-nonzero-true, string-size-unchecked: what it took, it sends back
            return faulty_stream_codec(codec, self.faults)
        return codec

    def _body_codec(self, where: str, nodes: Sequence[DataNode]) -> ValuesCodec[DataNode]:
        # fault: document-order-values, bool-nonzero-true, string-size-unchecked
        return faulty_codec(self.model, nodes, where, "R-RCTP-28", self.faults)

    def _session_ended(self, session_id: str) -> None:
        if Fault.PRIVILEGES_KEPT not in self.faults:  # fault: privileges-kept
            super()._session_ended(session_id)

    def _changed(self, paths: Iterable[str], by: S | None, now: float) -> None:
        if Fault.ECHO_OWN_WRITES in self.faults:  # fault: echo-own-writes
            by = None  # the session that made a change is told of it too
        super()._changed(paths, by, now)
