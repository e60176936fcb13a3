"""RCTP/2.0 control messages as data (specs/rctp-2.0.md §2)."""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from dataclasses import dataclass

VERSION = "RCTP/2.0"

#: The ten methods of the paper's Table 2 (D-RCTP-12).
METHODS = (
    "CONNECT",
    "ACQUIRE",
    "RELEASE",
    "READ",
    "WRITE",
    "SETUP",
    "GO",
    "PAUSE",
    "STOP",
    "BYE",
)
#: The methods a server may send (D-RCTP-12); a client may send all ten.
SERVER_METHODS = frozenset({"WRITE", "STOP", "BYE"})

#: D-RCTP-15.
REASONS = {
    200: "OK",
    400: "Bad Request",
    403: "Forbidden",
    404: "Not Found",
    405: "Method Not Allowed",
    411: "Length Required",
    413: "Content Too Large",
    414: "URI Too Long",
    415: "Unsupported Media Type",
    422: "Unprocessable Content",
    431: "Request Header Fields Too Large",
    454: "Session Not Found",
    455: "Method Not Valid in This State",
    461: "Unsupported Transport",
    470: "Not Acquired",
    471: "Acquired by Another Session",
    500: "Internal Server Error",
    501: "Not Implemented",
    503: "Service Unavailable",
    505: "RCTP Version Not Supported",
}

VALUES_TYPE = "application/rctp-values"
TEXT_TYPE = "text/plain; charset=utf-8"
#: D-RCTP-27: a change of a playing event access is pushed (the server's WRITE) within this many
#: seconds of the change, or of the answer that makes room for it.
PUSH_DELAY = 0.5


@dataclass(frozen=True, slots=True)
class Headers:
    """Header fields in the order they came, looked up case-insensitively."""

    fields: tuple[tuple[str, str], ...] = ()

    @classmethod
    def of(cls, fields: Iterable[tuple[str, str]]) -> Headers:
        return cls(tuple(fields))

    def get(self, name: str) -> str | None:
        wanted = name.lower()
        for field, value in self.fields:
            if field.lower() == wanted:
                return value
        return None

    def get_all(self, name: str) -> list[str]:
        wanted = name.lower()
        return [value for field, value in self.fields if field.lower() == wanted]

    def __contains__(self, name: object) -> bool:
        return isinstance(name, str) and self.get(name) is not None

    def __iter__(self) -> Iterator[tuple[str, str]]:
        return iter(self.fields)

    def __len__(self) -> int:
        return len(self.fields)

    def with_field(self, name: str, value: str) -> Headers:
        """These fields and one more, at the end."""
        return Headers((*self.fields, (name, value)))


@dataclass(frozen=True, slots=True)
class Request:
    method: str
    #: As on the wire: `*`, `/` or a percent-encoded node path (D-RCTP-7).
    target: str
    headers: Headers = Headers()
    body: bytes = b""
    version: str = VERSION


@dataclass(frozen=True, slots=True)
class Response:
    status: int
    reason: str
    headers: Headers = Headers()
    body: bytes = b""
    version: str = VERSION


Message = Request | Response
