"""Read RCTP/2.0 control messages from a byte stream, incrementally (specs/rctp-2.0.md §2).

Feed any split of bytes; take whole messages out, requests and responses alike (D-RCTP-5).
Nothing is buffered beyond the limits of D-RCTP-9, and scanning only moves forward, so a stream
fed one byte at a time costs no more than one fed at once. Every framing error is a
`RemoteProtocolError` at its offset in the stream, fatal (D-RCTP-10): after it, the stream's
message boundaries are unknown and the reader refuses to go on.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import NoReturn

from rcmlconf.rctp.errors import RemoteProtocolError
from rcmlconf.rctp.messages import Headers, Message, Request, Response


@dataclass(frozen=True, slots=True)
class Limits:
    """D-RCTP-9."""

    start_line: int = 4096
    header_line: int = 4096
    header_section: int = 16384
    header_fields: int = 64
    body: int = 4 * 1024 * 1024


LIMITS = Limits()

_TOKEN = re.compile(rb"[!#$%&'*+\-.^_`|~0-9A-Za-z]+")
# The grammar's quoted "RCTP/" matches in any letter case (RFC 5234 §2.3), so `rctp/2.0` parses;
# D-RCTP-30 then makes it another version than RCTP/2.0 (505, the connection's check), not 400.
_VERSION = re.compile(rb"(?i:RCTP)/[0-9]+\.[0-9]+")
_STATUS = re.compile(rb"[0-9]{3}")
# field-vchar, SP and HTAB (RFC 9110 field-value): no other control character.
_FIELD_VALUE = re.compile(rb"[\t\x20-\x7e\x80-\xff]*")
_DIGITS = re.compile(rb"[0-9]+")
#: The digits a Content-Length may have (the grammar's `1*10DIGIT`, D-RCTP-9's 4,194,304 in
#: reach): one of more does not parse, and is refused without being converted or shown whole.
MOST_DIGITS = 10
_LINE_ENDING_FAULT = re.compile(rb"\r(?!\n)|(?<!\r)\n")


@dataclass(frozen=True, slots=True)
class _Head:
    message: Message
    body_length: int


class MessageReader:
    def __init__(self, limits: Limits = LIMITS) -> None:
        self.limits = limits
        self._buffer = bytearray()
        #: Stream offset of the first byte in the buffer.
        self._base = 0
        #: How far the search for the end of the head has looked (never backwards).
        self._scanned = 0
        self._head: _Head | None = None
        self._failure: RemoteProtocolError | None = None

    @property
    def offset(self) -> int:
        """Stream offset of the next byte not yet part of a message."""
        return self._base

    @property
    def buffered(self) -> int:
        return len(self._buffer)

    def feed(self, data: bytes) -> None:
        self._buffer += data

    def next_message(self) -> Message | None:
        """The next whole message, or None until more bytes arrive."""
        if self._failure is not None:
            raise _detached(self._failure)
        try:
            return self._next()
        except RemoteProtocolError as error:
            self._failure = _detached(error)
            raise

    def _next(self) -> Message | None:
        if self._head is None:
            self._head = self._read_head()
            if self._head is None:
                return None
        head = self._head
        if len(self._buffer) < head.body_length:
            return None
        body = bytes(self._buffer[: head.body_length])
        self._consume(head.body_length)
        self._head = None
        message = head.message
        if not body:
            return message
        if isinstance(message, Request):
            return Request(message.method, message.target, message.headers, body, message.version)
        return Response(message.status, message.reason, message.headers, body, message.version)

    def _consume(self, count: int) -> None:
        del self._buffer[:count]
        self._base += count
        self._scanned = 0

    # -- the head: start line and header fields ------------------------------------------------

    def _read_head(self) -> _Head | None:
        buffer = self._buffer
        start = max(0, self._scanned - 3)
        end = buffer.find(b"\r\n\r\n", start)
        if end < 0:
            self._check_partial()
            self._scanned = len(buffer)
            return None
        self._check_line_endings(start, end)
        head = bytes(buffer[:end])
        lines = head.split(b"\r\n")
        is_response = lines[0].startswith(b"RCTP/")
        if len(lines[0]) > self.limits.start_line:
            self._fail("start line too long", 0, 414, is_response, "R-RCTP-16")
        if end - len(lines[0]) - 2 > self.limits.header_section:
            self._fail("header section too long", 0, 431, is_response, "R-RCTP-16")
        message = self._start_line(lines[0], is_response)
        headers = self._header_fields(lines[1:], len(lines[0]) + 2, is_response)
        body_length = self._body_length(headers, is_response)
        self._consume(end + 4)
        if isinstance(message, Request):
            message = Request(message.method, message.target, headers, b"", message.version)
        else:
            message = Response(message.status, message.reason, headers, b"", message.version)
        return _Head(message, body_length)

    def _check_partial(self) -> None:
        """Limits and line endings of a head not yet complete: refuse as soon as it is certain."""
        buffer = self._buffer
        self._check_line_endings(max(0, self._scanned - 1), len(buffer))
        is_response = buffer.startswith(b"RCTP/")
        line_end = buffer.find(b"\r\n")
        if (line_end < 0 and len(buffer) > self.limits.start_line + 1) or (
            line_end > self.limits.start_line
        ):
            self._fail("start line too long", 0, 414, is_response, "R-RCTP-16")
        # +4: the empty line that would end the section may be on its way
        if line_end >= 0 and len(buffer) - line_end - 2 > self.limits.header_section + 4:
            self._fail("header section too long", 0, 431, is_response, "R-RCTP-16")

    def _check_line_endings(self, start: int, end: int) -> None:
        """D-RCTP-4: CR only before LF, LF only after CR, in buffer[start:end]."""
        buffer = self._buffer
        for found in _LINE_ENDING_FAULT.finditer(buffer, start, end):
            if found.group() == b"\r" and found.end() == len(buffer):
                continue  # a CR at the very end may yet be followed by its LF
            self._fail(
                "a line ends in a bare CR or LF, not CRLF",
                found.start(),
                400,
                buffer.startswith(b"RCTP/"),
                "R-RCTP-1",
            )

    def _start_line(self, line: bytes, is_response: bool) -> Message:
        if is_response:
            parts = line.split(b" ", 2)
            if (
                len(parts) != 3
                or _VERSION.fullmatch(parts[0]) is None
                or _STATUS.fullmatch(parts[1]) is None
                or _FIELD_VALUE.fullmatch(parts[2]) is None
            ):
                self._fail("malformed status line", 0, 400, True, "R-RCTP-1")
            return Response(int(parts[1]), parts[2].decode("latin-1"), version=parts[0].decode())
        parts = line.split(b" ")
        if len(parts) != 3 or _TOKEN.fullmatch(parts[0]) is None or not parts[1]:
            self._fail("malformed request line (method SP target SP version)", 0, 400, False)
        # The target's syntax is checked by the connection: a bad target is answered 400 and the
        # connection goes on (R-RCTP-15), since the message is well framed.
        if _VERSION.fullmatch(parts[2]) is None:
            self._fail(
                f"{parts[2][:20]!r} is not an RCTP version",
                len(parts[0]) + len(parts[1]) + 2,
                400,
                False,
                "R-RCTP-2",
            )
        return Request(parts[0].decode(), parts[1].decode("latin-1"), version=parts[2].decode())

    def _header_fields(self, lines: list[bytes], offset: int, is_response: bool) -> Headers:
        if len(lines) > self.limits.header_fields:
            self._fail(
                f"more than {self.limits.header_fields} header fields",
                offset,
                431,
                is_response,
                "R-RCTP-16",
            )
        fields = []
        for line in lines:
            if len(line) > self.limits.header_line:
                self._fail("header line too long", offset, 431, is_response, "R-RCTP-16")
            if line[:1] in (b" ", b"\t"):
                self._fail("obsolete line folding", offset, 400, is_response, "R-RCTP-1")
            name, colon, value = line.partition(b":")
            if not colon or _TOKEN.fullmatch(name) is None:
                self._fail(
                    'malformed header field (name ":" value, no space before the colon)',
                    offset,
                    400,
                    is_response,
                    "R-RCTP-1",
                )
            value = value.strip(b" \t")
            if _FIELD_VALUE.fullmatch(value) is None:
                self._fail(
                    "a control character in a header field value",
                    offset + len(name) + 1,
                    400,
                    is_response,
                )
            fields.append((name.decode("ascii"), value.decode("latin-1")))
            offset += len(line) + 2
        return Headers(tuple(fields))

    def _body_length(self, headers: Headers, is_response: bool) -> int:
        """D-RCTP-4: Content-Length frames every body; Transfer-Encoding is refused."""
        if "Transfer-Encoding" in headers:
            self._fail("Transfer-Encoding is not used by RCTP/2.0", 0, 400, is_response, "R-RCTP-7")
        lengths = headers.get_all("Content-Length")
        if not lengths:
            return 0
        if len(lengths) > 1:
            self._fail("Content-Length is given more than once", 0, 400, is_response, "R-RCTP-6")
        digits = lengths[0].encode("latin-1")
        if _DIGITS.fullmatch(digits) is None:
            self._fail("Content-Length is not a decimal number", 0, 400, is_response, "R-RCTP-6")
        if len(digits) > MOST_DIGITS:
            self._fail(
                f"Content-Length has {len(digits):,} digits, more than the {MOST_DIGITS} of its"
                " grammar (1*10DIGIT)",
                0,
                400,
                is_response,
                "R-RCTP-6",
            )
        length = int(digits)
        if length > self.limits.body:
            self._fail(
                f"body of {length:,} bytes is above the limit of {self.limits.body:,}",
                0,
                413,
                is_response,
                "R-RCTP-16",
            )
        return length

    def _fail(
        self, reason: str, offset: int, status: int, is_response: bool, rule: str | None = None
    ) -> NoReturn:
        # D-RCTP-10: a broken response gets no answer
        raise RemoteProtocolError(
            reason, self._base + offset, status, rule, fatal=True, answerable=not is_response
        )


def _detached(error: RemoteProtocolError) -> RemoteProtocolError:
    """`error` again, with no traceback: one kept with its frames holds its reader in a cycle
    that only the collector frees, one per bad request under a flood (issue 18)."""
    return RemoteProtocolError(
        error.reason,
        error.offset,
        error.status,
        error.rule,
        fatal=error.fatal,
        answerable=error.answerable,
    )
