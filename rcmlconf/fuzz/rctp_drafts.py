"""RCTP/2.0 requests before they are bytes, and the valid ones a server's robot takes.

A `Draft` keeps each part of a request apart (start line, fields, body, line ending,
`Content-Length`), so that a mutation changes one part and the rest stays valid
(D-FUZZ-3). `render` writes it as the grammar of §2.1 says, or as the mutation left it.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from rcmlconf.fuzz.rctp_robot import RobotPaths
from rcmlconf.fuzz.steps import CLIENT_PORT, SESSION
from rcmlconf.rctp.messages import VALUES_TYPE, VERSION

#: `Content-Length` as the body's size; None leaves the field out.
AUTO = "auto"
Fields = tuple[tuple[str, str], ...]


@dataclass(frozen=True, slots=True)
class Draft:
    method: str
    target: str
    fields: Fields = ()
    body: bytes = b""
    version: str = VERSION
    eol: bytes = b"\r\n"
    #: The text of `Content-Length`: AUTO (the body's size, when there is a body) or as given.
    length: str | None = AUTO

    def with_cseq(self, cseq: int) -> Draft:
        return replace(self, fields=(("CSeq", str(cseq)), *self.fields))

    def render(self) -> bytes:
        eol = self.eol
        head = [f"{self.method} {self.target} {self.version}".encode("latin-1", "replace")]
        head += [f"{name}: {value}".encode("latin-1", "replace") for name, value in self.fields]
        length = str(len(self.body)) if self.length == AUTO and self.body else self.length
        if length is not None and length != AUTO:
            head.append(b"Content-Length: " + length.encode("latin-1", "replace"))
        return eol.join(head) + eol + eol + self.body


def answer(status: int, reason: str, fields: Fields, body: bytes = b"") -> Draft:
    """An answer as a Draft (D-FUZZ-8): a status line's version, status and reason stand where
    a request line's method, target and version do, so one renderer and the field mutations
    serve both."""
    return Draft(VERSION, str(status), fields, body, version=reason)


def _session(draft: Draft) -> Draft:
    return replace(draft, fields=(*draft.fields, ("Session", SESSION.decode())))


def _values(draft: Draft, body: bytes) -> Draft:
    return replace(draft, fields=(*draft.fields, ("Content-Type", VALUES_TYPE)), body=body)


def _transport(robot: RobotPaths) -> str:
    mode = "both" if robot.stream_writes else "read"
    return f"udp;client_port={CLIENT_PORT.decode()};mode={mode}"


#: D-FUZZ-2: a playing stream the server has sent STOP of, for its receive timeout, and whose
#: STOP the fuzzer leaves unanswered.
STOP_UNANSWERED = "stop unanswered"
#: The states a valid prefix reaches on a server (D-FUZZ-2), in the order they build on each
#: other.
STATES = (
    "connected",
    "session",
    "acquired",
    "stream ready",
    "playing",
    STOP_UNANSWERED,
    "event playing",
    "closing",
)


def prefix(state: str, robot: RobotPaths) -> list[Draft] | None:
    """The requests that take a new connection to `state`, without `CSeq`; None when the
    robot has nothing to reach it with (no stream access for "playing")."""
    connect = Draft("CONNECT", robot.site, (("User-Agent", "rcmlconf-fuzz"),))
    stream = robot.stream
    if state == "connected":
        return []
    if state == "session":
        return [connect]
    if state == "acquired":
        return [connect, _session(Draft("ACQUIRE", "/"))]
    if state == STOP_UNANSWERED:
        # Only a stream the server receives on has a receive timeout to end it (R-RCTP-45).
        return prefix("playing", robot) if robot.stream_writes else None
    if state in ("stream ready", "playing"):
        if stream is None:
            return None
        setup = _session(Draft("SETUP", stream.path, (("Transport", _transport(robot)),)))
        drafts = [connect]
        if robot.stream_writes:
            drafts.append(_session(Draft("ACQUIRE", stream.path)))
        drafts.append(setup)
        if state == "playing":
            drafts.append(_session(Draft("GO", stream.path)))
        return drafts
    if state == "event playing":
        if robot.event is None:
            return None
        event = robot.event.path
        return [connect, _session(Draft("SETUP", event)), _session(Draft("GO", event))]
    if state == "closing":
        return [connect, _session(Draft("BYE", "*"))]
    raise ValueError(f"no state {state!r}")


def moves(robot: RobotPaths) -> list[Draft]:
    """Valid requests of every method, on the robot's own nodes: what mutations start from."""
    found = [
        Draft("CONNECT", robot.site, (("User-Agent", "rcmlconf-fuzz"),)),
        _session(Draft("CONNECT", robot.site)),
        _session(Draft("ACQUIRE", "/")),
        _session(Draft("RELEASE", "*")),
        _session(Draft("BYE", "*")),
    ]
    if robot.readable is not None:
        found.append(_session(Draft("READ", robot.readable.path)))
    if robot.writable is not None:
        found.append(
            _values(_session(Draft("WRITE", robot.writable.path)), robot.zero_body(robot.writable))
        )
    if robot.stream is not None:
        path = robot.stream.path
        found.append(_session(Draft("SETUP", path, (("Transport", _transport(robot)),))))
        found += [_session(Draft(method, path)) for method in ("GO", "PAUSE", "STOP")]
        found.append(_session(Draft("ACQUIRE", path)))
        found.append(_session(Draft("RELEASE", path)))
    if robot.event is not None:
        names = ", ".join(node.name for node in robot.event.readable())
        event = robot.event.path
        found.append(_session(Draft("READ", event, (("Nodes", names),) if names else ())))
        found += [_session(Draft(method, event)) for method in ("SETUP", "GO", "PAUSE", "STOP")]
    return found
