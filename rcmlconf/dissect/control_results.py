"""What the dissector tells of an RCTP/2.0 control connection: the `Record.extra` of its messages
(`Answer`, `BodyValues`) and its part of the analysis (`ControlReport`, from its `Exchange`s)."""

from __future__ import annotations

from dataclasses import dataclass

from rcmlconf.rctp.messages import Request
from rcmlconf.values import Value


@dataclass(frozen=True, slots=True)
class Answer:
    """`Record.extra` of a response: the request it answers, and how long that took."""

    request: Request
    #: Seconds from the request's last byte to the response's, as the capture saw them.
    elapsed: float
    #: The request's record number.
    message: int
    #: The values of a READ's answer, decoded with the RCML (D-RCTP-8), by node name.
    values: dict[str, Value] | None = None


@dataclass(frozen=True, slots=True)
class BodyValues:
    """`Record.extra` of a WRITE whose body the RCML decodes: its values, by node name."""

    values: dict[str, Value]


@dataclass(frozen=True, slots=True)
class Exchange:
    method: str
    #: Who sent the request.
    by: str
    elapsed: float


@dataclass(frozen=True, slots=True)
class ControlReport:
    """One control connection, for the analysis."""

    client: str
    server: str
    session: str | None
    timeout: int | None
    state: str
    requests: int
    responses: int
    malformed: int
    #: method -> (count, min, median, max) seconds of its request-to-response times.
    response_times: dict[str, tuple[int, float, float, float]]
    #: Access path -> its stream state at the end (D-RCTP-14).
    streams: dict[str, str]
    #: The requests their receiver had to refuse on its own (D-RCTP-25, D-RCTP-13, D-RCTP-14):
    #: (message number, status due or None for dropped unanswered, rule), in message order.
    refused: tuple[tuple[int, int | None, str], ...]
    #: Segments that repeated bytes already seen, segments ahead of a hole, and holes the
    #: capture never filled (bytes lost to the capture).
    retransmissions: int
    out_of_order: int
    holes: int
    first: float
    last: float
