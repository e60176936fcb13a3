"""The session of a faulty reference server (`reference.faults`).

The rules of a server's session live in the core's `ServerSession`. The faults are not put
there. A server with faults makes its sessions of this subclass instead (`ReferenceServer`).
Each fault breaks one rule, in the method where such a bug would sit. The faults of the data
stream are in the endpoint this session makes (`faulty_stream.FaultyEndpoint`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from rcmlconf.errors import ValueTextError
from rcmlconf.rcml.model import DataNode, Permission
from rcmlconf.rctp.datastream.endpoint import Endpoint
from rcmlconf.rctp.fields import Transport
from rcmlconf.rctp.messages import Request
from rcmlconf.rctp.states import Role, SessionState
from rcmlconf.rctp.targets import Target
from rcmlconf.reference.faults import STREAM_FAULTS, Fault, nan_blind
from rcmlconf.reference.server.faulty_stream import FaultyEndpoint
from rcmlconf.reference.server.session import Answer, Refused, ServerSession
from rcmlconf.values import Value


class FaultySession(ServerSession):
    def __init__(self, faults: frozenset[Fault], *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.faults = faults

    # -- the control connection ----------------------------------------------------------------

    def _protocol_failed(self) -> None:
        if Fault.OPEN_AFTER_BAD_FRAMING in self.faults:  # fault: open-after-bad-framing
            self.conn.session_state = SessionState.CLOSED  # the connection stays open
        else:
            super()._protocol_failed()

    def _connect(self, request: Request, target: Target, now: float) -> Answer:
        refresh = self.id is not None
        answer = super()._connect(request, target, now)
        if refresh and Fault.REFRESH_REFUSED in self.faults:  # fault: refresh-refused
            raise Refused(455, "this connection has a session already", "R-RCTP-22")
        return answer

    def _same_token(self, given: str | None, token: str) -> bool:
        if Fault.CASE_SENSITIVE_TOKENS in self.faults:  # fault: case-sensitive-tokens
            return given == token
        return super()._same_token(given, token)

    def _parse_transport(self, text: str) -> Transport:
        if Fault.CASE_SENSITIVE_TOKENS in self.faults and text != text.lower():
            raise ValueTextError(f"Transport {text!r} is not in lower case")  # fault
        return super()._parse_transport(text)

    # -- nodes and privileges ------------------------------------------------------------------

    def _permitted(self, node: DataNode, needed: Permission) -> None:
        if Fault.PERMISSION_IGNORED not in self.faults:  # fault: permission-ignored
            super()._permitted(node, needed)

    def _privileged(self, path: str) -> None:
        unheld = self.robot.privileges.holder(path) is None
        if unheld and Fault.WRITE_WITHOUT_ACQUIRE in self.faults:  # fault: write-without-acquire
            return  # as if this session held the path
        super()._privileged(path)

    def _writing_below(self, target: Target) -> list[str]:
        if Fault.RELEASE_WHILE_WRITING in self.faults:  # fault: release-while-writing
            return []
        return super()._writing_below(target)

    def _out_of_range(self, node: DataNode, value: Value) -> str | None:
        if Fault.NAN_IN_RANGE in self.faults:  # fault: nan-in-range
            return nan_blind(node, value)
        return super()._out_of_range(node, value)

    def _apply(self, nodes: Sequence[DataNode], values: Mapping[str, Value], now: float) -> None:
        try:
            super()._apply(nodes, values, now)
        except Refused:
            if Fault.PARTIAL_WRITE in self.faults:  # fault: partial-write
                fine = [n for n in nodes if n.out_of_range(values[n.name]) is None]
                self.robot.command(self, {n.path: values[n.name] for n in fine}, now)
            raise

    # -- the data stream -----------------------------------------------------------------------

    def _new_endpoint(self, tag: int, first_sequence: int) -> Endpoint:
        faults = self.faults & STREAM_FAULTS
        if not faults:
            return super()._new_endpoint(tag, first_sequence)
        unix_offset = self.robot.unix_offset
        return FaultyEndpoint(
            faults, Role.SERVER, tag, first_sequence=first_sequence, unix_offset=unix_offset
        )

    def _stream_to(self, endpoint: Endpoint, client_port: int) -> None:
        if Fault.FIRST_CLIENT_PORT in self.faults and endpoint.peer is not None:
            return  # fault: first-client-port
        super()._stream_to(endpoint, client_port)

    def _pause_stream(self, path: str) -> None:
        if Fault.PAUSE_IGNORED not in self.faults:  # fault: pause-ignored
            super()._pause_stream(path)

    def _stream_lost(self, stream: int, now: float) -> None:
        if Fault.NO_TIMEOUT_STOP not in self.faults:  # fault: no-timeout-stop
            super()._stream_lost(stream, now)

    # -- the server's own requests -------------------------------------------------------------

    def _room(self) -> int:
        if Fault.UNBOUNDED_PUSHES in self.faults:  # fault: unbounded-pushes
            return len(self._stops) + len(self._changes)
        return super()._room()

    def _push(self, access_path: str, names: set[str], now: float) -> None:
        if Fault.NO_CHANGE_PUSH not in self.faults:  # fault: no-change-push
            super()._push(access_path, names, now)
