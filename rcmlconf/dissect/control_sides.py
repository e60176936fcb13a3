"""One direction of an RCTP/2.0 control connection (`Side`: what one end sent, put in order and
framed) and each of its requests until it is answered (`Sent`)."""

from __future__ import annotations

from collections import deque

from rcmlconf.dissect.records import Endpoints
from rcmlconf.dissect.tcp import TcpStream
from rcmlconf.rctp.messages import Request
from rcmlconf.rctp.reader import MessageReader

#: The roles of the ends (`Side.role`).
CLIENT = "client"
SERVER = "server"


class Sent:
    """A request, until it is answered."""

    __slots__ = ("checked", "cseq", "due", "expected", "frame", "number", "request", "time")

    def __init__(self, request: Request, cseq: int | None, number: int, frame: int, time: float):
        self.request = request
        self.cseq = cseq
        self.number = number
        self.frame = frame
        self.time = time
        self.checked = False
        #: The CSeq that was next when this one came instead (R-RCTP-4), or None.
        self.expected: int | None = None
        #: (status due, why, rule) when the request's receiver must refuse it; status None for
        #: a request that is dropped unanswered (after the session closed).
        self.due: tuple[int | None, str, str] | None = None


class Side:
    """One direction: what one end sent."""

    __slots__ = (
        "address",
        "dead",
        "endpoints",
        "malformed",
        "next_cseq",
        "pending",
        "pieces",
        "port",
        "reader",
        "requests",
        "responses",
        "role",
        "tcp",
    )

    def __init__(self, endpoints: Endpoints, address: bytes, port: int) -> None:
        self.endpoints = endpoints
        self.address = address
        self.port = port
        self.role: str | None = None
        self.tcp = TcpStream()
        self.reader = MessageReader()
        #: Framing is lost (a message that cannot be framed, or a hole in the capture).
        self.dead = False
        #: (stream offset, frame, time, file offset of that byte or -1), one per piece fed.
        self.pieces: list[tuple[int, int, float, int]] = []
        self.next_cseq: int | None = None
        #: This side's requests not yet answered, oldest first.
        self.pending: deque[Sent] = deque()
        self.requests = 0
        self.responses = 0
        self.malformed = 0
