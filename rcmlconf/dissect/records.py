"""What the dissector makes of a capture: one `Record` per message, and `Finding`s.

A record is made for every message of a capture, a million of them for a large one: it is a
NamedTuple made by `tuple.__new__` (`make_record`), as the RSP codec makes its headers, and holds
what the core's codec decoded (`value`) rather than a copy of its fields: the text and JSON forms
are derived from it by `rcmlconf.dissect.output`.
"""

from __future__ import annotations

import enum
import json as _json
from dataclasses import dataclass
from typing import Any, Final, NamedTuple

#: The protocols the dissector decodes, as `--decode-as` names them.
RCTP: Final = "rctp"
RCTP_DATA: Final = "rctp-data"
RSP: Final = "rsp"
PROTOCOLS: Final = (RCTP, RCTP_DATA, RSP)
#: How a summary line names them.
LABELS: Final = {RCTP: "RCTP", RCTP_DATA: "RCTP-DATA", RSP: "RSP"}


class Severity(enum.Enum):
    #: A MUST of specs/ broken by what went over the wire.
    ERROR = "error"
    #: A SHOULD broken, or something a receiver must refuse (and should have).
    WARNING = "warning"
    #: What the capture shows of how the protocol went: not a fault.
    NOTE = "note"


@dataclass(frozen=True, slots=True)
class Endpoints:
    """One direction of a conversation: made once per flow, shared by its records."""

    source: str
    destination: str
    protocol: str
    #: `source → destination PROTOCOL`, the middle of a summary line, made once.
    text: str = ""
    #: `"source":...,"destination":...,"protocol":...`, the same in a JSON line, made once.
    json: str = ""

    def __post_init__(self) -> None:
        if not self.text:
            label = LABELS.get(self.protocol, self.protocol.upper())
            object.__setattr__(self, "text", f"{self.source} → {self.destination} {label}")
        if not self.json:
            fields = {"source": self.source, "destination": self.destination}
            fields["protocol"] = self.protocol
            text = _json.dumps(fields, ensure_ascii=False, separators=(",", ":"))
            object.__setattr__(self, "json", text[1:-1])


@dataclass(frozen=True, slots=True)
class Malformed:
    """Why a message could not be decoded, and where."""

    reason: str
    #: From the first byte of the datagram (UDP) or of the direction's byte stream (TCP).
    offset: int
    rule: str | None
    #: The same byte in the capture file, when it is in the file in one piece.
    file_offset: int | None


class Record(NamedTuple):
    """One message: an RCTP control message, a data-stream packet or an RSP packet.

    Immutable, like a frozen dataclass, but a NamedTuple: one is made per message, a million for
    a large capture, and a frozen dataclass of nine fields costs four times as much to make
    (the reason `rsp.codec.header.Header` is one too).
    """

    #: 1, 2, 3, ... in the order the messages were decoded.
    number: int
    #: The capture's frame (1-based) that carried the message, or its last byte for TCP.
    frame: int
    #: Unix seconds, as the capture stamped the frame.
    time: float
    flow: Endpoints
    #: Method, status ("200 OK"), or packet type ("UPLINK", "DATA+FLOW").
    kind: str
    #: CSeq, or the packet's sequence number.
    sequence: int | None
    #: What the core's codec decoded: a `rctp.messages.Request` or `Response`, a
    #: `rctp.datastream.packets.Packet`, or a `dissect.rsp.RspPacket` (header and body).
    value: Any
    malformed: Malformed | None
    #: Derived by the dissector: the request a response answers and how long it took
    #: (`control.Answer`), a data-stream packet's values decoded with the RCML
    #: (`datastream.DataValues`); None for most records.
    extra: Any = None

    @property
    def protocol(self) -> str:
        return self.flow.protocol

    @property
    def source(self) -> str:
        return self.flow.source

    @property
    def destination(self) -> str:
        return self.flow.destination


_new = tuple.__new__


def make_record(
    number: int,
    frame: int,
    time: float,
    flow: Endpoints,
    kind: str,
    sequence: int | None,
    value: Any,
    malformed: Malformed | None,
    extra: Any = None,
) -> Record:
    """`Record(...)`, made without the call to its `__new__`."""
    return _new(Record, (number, frame, time, flow, kind, sequence, value, malformed, extra))


@dataclass(frozen=True, slots=True)
class Finding:
    """Something the analysis found, tied to the requirement of specs/ it concerns."""

    severity: Severity
    rule: str
    text: str
    #: Where: the frame, its time and the message's number (0 when no one message is at fault).
    frame: int = 0
    time: float | None = None
    message: int = 0
    #: The byte of the capture file at fault, when there is one.
    file_offset: int | None = None
