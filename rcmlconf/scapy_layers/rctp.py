"""
RCTP/2.0: the control connection and the data stream (specs/rctp-2.0.md)

Control messages (§2) are HTTP/1.1-like text over TCP port 7330: a start line, header fields, an
empty line and a body framed by ``Content-Length``. Either side sends requests (D-RCTP-5), so a
message is a request or a response by its first line, in both directions. ``RCTP`` is bound to the
TCP port and picks ``RCTPRequest`` or ``RCTPResponse``; its ``tcp_reassemble`` gives whole
messages from a ``TCPSession`` however TCP split or joined them (R-RCTP-13)::

    >>> from rcmlconf.scapy_layers import rctp
    >>> packets = sniff(offline="session.pcap", session=TCPSession)
    >>> packets[3][rctp.RCTPRequest].header("CSeq")

The data stream (§6) is UDP: ``RCTPStream``, a 16-byte header and its payloads (D-RCTP-19) —
DATA (D-RCTP-20, the values still encoded: decoding them needs the RCML), FLOW with its request,
ACK or NACK fields (D-RCTP-22; a heartbeat carries T1, T2, T3), and any other type kept as bytes
(R-RCTP-51). Its ports are negotiated by SETUP's ``Transport``: ``bind_port`` decodes another.

A second implementation of the wire format, kept apart from ``rcmlconf.rctp`` on purpose (as
scapy's contrib layers are apart from the implementations they dissect): the tests check both
against every vector. Bytes that cannot be framed are left to scapy's ``Raw``, never raised.
"""

# scapy.contrib.description = RCTP/2.0 control messages and data stream (RCML 2.0)
# scapy.contrib.status = loads

from __future__ import annotations

import re
import struct
from datetime import UTC, datetime
from typing import Any

from scapy.config import conf
from scapy.fields import (
    ByteEnumField,
    ByteField,
    ConditionalField,
    Field,
    FieldLenField,
    IntField,
    PacketListField,
    ShortField,
    StrField,
    StrLenField,
    XIntField,
)
from scapy.layers.inet import TCP, UDP
from scapy.packet import Packet, bind_bottom_up, bind_layers, bind_top_down

from rcmlconf.rcml.url import DEFAULT_PORT
from rcmlconf.rctp.messages import REASONS, VERSION
from rcmlconf.rctp.reader import LIMITS, MOST_DIGITS

# The numbers of specs/rctp-2.0.md, taken from the core so that the layer and the codec it is
# checked against cannot disagree on them.
RCTP_PORT = DEFAULT_PORT
RCTP_VERSION = VERSION.encode("ascii")

#: D-RCTP-15: status codes and their reason phrases.
RCTP_STATUS_CODES = dict(REASONS)

#: D-RCTP-9: what a receiver reads of one message at most.
MAX_START_LINE = LIMITS.start_line
MAX_HEADER_LINE = LIMITS.header_line
MAX_HEADER_SECTION = LIMITS.header_section
MAX_HEADER_FIELDS = LIMITS.header_fields
MAX_BODY = LIMITS.body

#: D-RCTP-19, D-RCTP-22: the data stream's numbers and what they mean.
RCTP_STREAM_VERSION = 2
RCTP_PAYLOAD_TYPES = {1: "DATA", 2: "FLOW"}
RCTP_FLOW_MESSAGES = {0: "request", 1: "ACK", 2: "NACK"}
RCTP_FLOW_OPERATIONS = {
    1: "heartbeat",
    2: "get interval",
    3: "set interval",
    4: "get timeout",
    5: "set timeout",
}
RCTP_DIRECTIONS = {1: "read", 2: "write"}
RCTP_NACK_REASONS = {
    1: "unknown operation",
    2: "unknown stream",
    3: "value refused",
    4: "not permitted",
    5: "malformed",
}
#: Bytes of a FLOW body's fields after its 4-byte preamble, by (message, operation).
RCTP_FLOW_FIELDS = {
    (0, 1): 8,
    (1, 1): 24,
    (0, 2): 1,
    (1, 2): 5,
    (0, 3): 5,
    (1, 3): 5,
    (0, 4): 1,
    (1, 4): 5,
    (0, 5): 5,
    (1, 5): 5,
}

#: RFC 5905: seconds from 1900 (NTP's era 0) to 1970.
_NTP_TO_UNIX = 2208988800


# -- framing (D-RCTP-4, D-RCTP-9) -----------------------------------------------------------------


class FramingError(ValueError):
    """Bytes that cannot be the start of an RCTP message, or a message whose length is unknown."""

    def __init__(self, reason: str, offset: int = 0) -> None:
        super().__init__(f"{reason} (at byte {offset})")
        self.reason = reason
        self.offset = offset


_TOKEN = re.compile(rb"[!#$%&'*+\-.^_`|~0-9A-Za-z]+")
_VERSION = re.compile(rb"(?i:RCTP)/[0-9]+\.[0-9]+")  # rctp/2.0 parses: another version
_STATUS = re.compile(rb"[0-9]{3}")
_FIELD_VALUE = re.compile(rb"[\t\x20-\x7e\x80-\xff]*")
_DIGITS = re.compile(rb"[0-9]+")
_BARE = re.compile(rb"\r(?!\n)|(?<!\r)\n")


def _check_line_endings(data: bytes, end: int) -> None:
    for found in _BARE.finditer(data, 0, end):
        if found.group() == b"\r" and found.end() == len(data):
            continue  # its LF may be in the next segment
        raise FramingError("a line ends in a bare CR or LF, not CRLF", found.start())


def _check_start_line(line: bytes) -> None:
    if line.startswith(b"RCTP/"):
        parts = line.split(b" ", 2)
        if (
            len(parts) != 3
            or not _VERSION.fullmatch(parts[0])
            or not _STATUS.fullmatch(parts[1])
            or not _FIELD_VALUE.fullmatch(parts[2])
        ):
            raise FramingError("malformed status line")
        return
    parts = line.split(b" ")
    if len(parts) != 3 or not _TOKEN.fullmatch(parts[0]) or not parts[1]:
        raise FramingError("malformed request line (method SP target SP version)")
    if not _VERSION.fullmatch(parts[2]):
        raise FramingError("not an RCTP version", len(parts[0]) + len(parts[1]) + 2)


def _split_field(line: bytes) -> tuple[bytes, bytes]:
    name, _, value = line.partition(b":")
    return name, value.strip(b" \t")


def _check_start(data: bytes) -> None:
    """The start of a start line not yet complete: a method token, or a status line's version."""
    if data.startswith(b"RCTP/") or b"RCTP/".startswith(data):
        return
    word = data.split(b" ", 1)[0]
    if not _TOKEN.fullmatch(word):
        raise FramingError("not the start of a request line or a status line")


def _body_length(lines: list[bytes], first: int) -> int:
    """The body length the header fields give: D-RCTP-4, D-RCTP-9."""
    lengths = []
    offset = first
    for line in lines:
        if len(line) > MAX_HEADER_LINE:
            raise FramingError("header line too long", offset)
        if line[:1] in (b" ", b"\t"):
            raise FramingError("obsolete line folding", offset)
        name, colon, _ = line.partition(b":")
        if not colon or not _TOKEN.fullmatch(name):
            raise FramingError("malformed header field", offset)
        name, value = _split_field(line)
        if not _FIELD_VALUE.fullmatch(value):
            raise FramingError("a control character in a header field value", offset)
        lowered = name.lower()
        if lowered == b"transfer-encoding":
            raise FramingError("Transfer-Encoding is not used by RCTP/2.0", offset)
        if lowered == b"content-length":
            lengths.append(value)
        offset += len(line) + 2
    if not lengths:
        return 0
    if len(lengths) > 1:
        raise FramingError("Content-Length is given more than once")
    if not _DIGITS.fullmatch(lengths[0]):
        raise FramingError("Content-Length is not a decimal number")
    if len(lengths[0]) > MOST_DIGITS:
        raise FramingError(
            f"Content-Length has {len(lengths[0]):,} digits, more than the {MOST_DIGITS} of its"
            " grammar (1*10DIGIT)"
        )
    length = int(lengths[0])
    if length > MAX_BODY:
        raise FramingError(f"a body of {length} bytes, above {MAX_BODY}")
    return length


def message_length(data: bytes) -> int | None:
    """Bytes of the RCTP message that starts `data`, head and body, as soon as its head is
    complete (the body may not be there yet); None while the head is incomplete.

    Raises `FramingError` for bytes no RCTP message starts with, as soon as that is certain.
    """
    end = data.find(b"\r\n\r\n")
    if end < 0:
        _check_line_endings(data, len(data))
        line_end = data.find(b"\r\n")
        if (line_end < 0 and len(data) > MAX_START_LINE + 1) or line_end > MAX_START_LINE:
            raise FramingError("start line too long")
        _check_start(data if line_end < 0 else data[:line_end])
        if line_end >= 0:
            _check_start_line(data[:line_end])
            if len(data) - line_end - 2 > MAX_HEADER_SECTION + 4:
                raise FramingError("header section too long", line_end + 2)
        return None
    _check_line_endings(data, end)
    lines = data[:end].split(b"\r\n")
    if len(lines[0]) > MAX_START_LINE:
        raise FramingError("start line too long")
    if end - len(lines[0]) - 2 > MAX_HEADER_SECTION:
        raise FramingError("header section too long", len(lines[0]) + 2)
    _check_start_line(lines[0])
    if len(lines) - 1 > MAX_HEADER_FIELDS:
        raise FramingError(f"more than {MAX_HEADER_FIELDS} header fields", len(lines[0]) + 2)
    return end + 4 + _body_length(lines[1:], len(lines[0]) + 2)


# -- control message fields ----------------------------------------------------------------------


class _TextField(StrField):
    """Bytes up to a separator (SP, CRLF), shown as text."""

    __slots__ = ["separator"]

    def __init__(self, name: str, default: bytes, separator: bytes) -> None:
        super().__init__(name, default)
        self.separator = separator

    def getfield(self, pkt: Packet, s: bytes) -> tuple[bytes, bytes]:
        end = s.find(self.separator)
        if end < 0:
            return b"", s
        return s[end + len(self.separator) :], s[:end]

    def addfield(self, pkt: Packet, s: bytes, val: Any) -> bytes:
        return s + self.i2m(pkt, val) + self.separator

    def i2repr(self, pkt: Packet | None, x: Any) -> str:
        return repr(self.i2m(pkt, x).decode("latin-1"))


class _StatusField(Field[int, bytes]):
    """A status line's three digits."""

    def __init__(self, name: str, default: int) -> None:
        super().__init__(name, default, "3s")

    def getfield(self, pkt: Packet, s: bytes) -> tuple[bytes, int]:
        code, _, rest = s.partition(b" ")
        return rest, int(code) if code.isdigit() else 0

    def addfield(self, pkt: Packet, s: bytes, val: int | None) -> bytes:
        return s + b"%03d " % (val or 0)

    def i2repr(self, pkt: Packet | None, x: int) -> str:
        return str(x)


def _indented(field: Field[Any, Any], lines: list[str]) -> str:
    """Lines of a multi-line value, lined up under the first in `show()` (which indents the
    next ones by the field name's length, not by the padded name's)."""
    return ("\n" + " " * max(0, 10 - len(field.name))).join(lines)


class _HeadersField(Field[list[tuple[str, str]], bytes]):
    """Header fields in wire order, as (name, value) text; the empty line that ends them."""

    islist = 1
    ismutable = True

    def __init__(self, name: str, default: list[tuple[str, str]] | None) -> None:
        super().__init__(name, default, "0s")

    def getfield(self, pkt: Packet, s: bytes) -> tuple[bytes, list[tuple[str, str]]]:
        if s.startswith(b"\r\n"):
            return s[2:], []
        end = s.find(b"\r\n\r\n")
        if end < 0:
            block, rest = s, b""
        else:
            block, rest = s[:end], s[end + 4 :]
        fields = []
        for line in block.split(b"\r\n"):
            name, value = _split_field(line)
            fields.append((name.decode("latin-1"), value.decode("latin-1")))
        return rest, fields

    def addfield(self, pkt: Packet, s: bytes, val: list[tuple[str, str]] | None) -> bytes:
        lines = [f"{name}: {value}\r\n".encode("latin-1") for name, value in val or []]
        return s + b"".join(lines) + b"\r\n"

    def i2len(self, pkt: Packet, x: Any) -> int:
        return len(self.addfield(pkt, b"", x))

    def i2repr(self, pkt: Packet | None, x: list[tuple[str, str]] | None) -> str:
        if not x:
            return "(none)"
        return _indented(self, [f"{name}: {value}" for name, value in x])

    def do_copy(self, x: list[tuple[str, str]]) -> list[tuple[str, str]]:
        return list(x)


class _BodyField(StrField):
    """The body: exactly `Content-Length` bytes (D-RCTP-4), or what arrived of them."""

    def getfield(self, pkt: Packet, s: bytes) -> tuple[bytes, bytes]:
        length = pkt.content_length()
        return s[length:], s[:length]

    def i2repr(self, pkt: Packet | None, x: bytes) -> str:
        if not x:
            return "b''"
        shown = repr(x[:64]) + ("..." if len(x) > 64 else "")
        return f"{shown} ({len(x)} bytes)"


# -- control messages ----------------------------------------------------------------------------


class RCTP(Packet):
    """An RCTP control message, as TCP carries it: a request or a response by its first line
    (D-RCTP-5), or ``Raw`` when the bytes cannot be framed (D-RCTP-10)."""

    name = "RCTP"

    @classmethod
    def dispatch_hook(cls, _pkt: bytes | None = None, *args: Any, **kargs: Any) -> type[Packet]:
        if cls is not RCTP or not _pkt:
            return cls
        try:
            if message_length(_pkt) is None:
                return conf.raw_layer
        except FramingError:
            return conf.raw_layer
        return RCTPResponse if _pkt.startswith(b"RCTP/") else RCTPRequest

    @classmethod
    def tcp_reassemble(
        cls, data: bytes, metadata: dict[str, Any], session: dict[str, Any]
    ) -> Packet | None:
        """Whole messages from the bytes of one direction of a connection (R-RCTP-13): None
        until the first is complete; then every complete one, chained, and what follows them
        as ``Padding`` for the next call. Bytes that cannot be framed are returned as ``Raw``.

        All the complete messages at once, not one per call: TCPSession (scapy 2.6 to 2.8)
        misplaces the next segment's bytes when it calls back more than once for the Padding
        of one segment (two pipelined messages and the start of a third)."""
        end = 0
        while True:
            try:
                length = message_length(data[end:])
            except FramingError:
                if end:
                    break
                return conf.raw_layer(data)
            if length is None or end + length > len(data):
                if length is not None and not end:
                    metadata["tcp_min_len"] = length  # nothing to do until then
                break
            end += length
            if end == len(data):
                break
        if not end:
            if metadata.get("tcp_end"):
                return RCTP(data)  # the connection ended: what arrived of the message
            return None
        packet = RCTP(data[:end])
        if end < len(data):
            packet = packet / conf.padding_layer(data[end:])
        return packet

    def guess_payload_class(self, payload: bytes) -> type[Packet]:
        return RCTP  # the next message pipelined after this one, or Raw


class _RCTPMessage(RCTP):
    def header(self, name: str) -> str | None:
        """The value of the first header field `name` (case-insensitive), or None."""
        wanted = name.lower()
        for field, value in self.headers or ():
            if field.lower() == wanted:
                return str(value)
        return None

    def header_all(self, name: str) -> list[str]:
        wanted = name.lower()
        return [str(value) for field, value in self.headers or () if field.lower() == wanted]

    def content_length(self) -> int:
        value = self.header("Content-Length")
        if value is None or not value.isdigit():
            return 0
        return int(value)

    def describe(self) -> str:
        """The start line's method and target or status, and the CSeq, on one line."""
        raise NotImplementedError

    def mysummary(self) -> Any:
        # Every message of a pipelined chain in the summary, not only the last: scapy takes
        # (text, the classes below whose summaries to show too).
        return self.describe(), [RCTPRequest, RCTPResponse]

    def _cseq(self) -> str:
        cseq = self.header("CSeq")
        return f" CSeq={cseq}" if cseq is not None else ""

    def _body_note(self) -> str:
        return f" ({len(self.body)} bytes)" if self.body else ""


class RCTPRequest(_RCTPMessage):
    name = "RCTP Request"
    # request-line    = method SP request-target SP version CRLF
    # *( header-field CRLF ) CRLF [ body ]                        (D-RCTP-4, specs §2.1)
    fields_desc = [  # noqa: RUF012 (scapy reads the class attribute)
        _TextField("method", b"CONNECT", b" "),
        _TextField("target", b"/", b" "),
        _TextField("version", RCTP_VERSION, b"\r\n"),
        _HeadersField("headers", []),
        _BodyField("body", b""),
    ]

    def describe(self) -> str:
        method = self.method.decode("latin-1")
        target = self.target.decode("latin-1")
        return f"RCTP {method} {target}{self._cseq()}{self._body_note()}"


class RCTPResponse(_RCTPMessage):
    name = "RCTP Response"
    # status-line     = version SP status-code SP reason-phrase CRLF
    # *( header-field CRLF ) CRLF [ body ]                        (D-RCTP-4, specs §2.1)
    fields_desc = [  # noqa: RUF012 (scapy reads the class attribute)
        _TextField("version", RCTP_VERSION, b" "),
        _StatusField("status", 200),
        _TextField("reason", b"OK", b"\r\n"),
        _HeadersField("headers", []),
        _BodyField("body", b""),
    ]

    def describe(self) -> str:
        reason = self.reason.decode("latin-1")
        return f"RCTP {self.status} {reason}{self._cseq()}{self._body_note()}"


# -- data stream fields --------------------------------------------------------------------------


def ntp_to_datetime(value: int) -> datetime:
    """A 64-bit NTP time (RFC 5905) with RFC 4330's era rule: a seconds field whose top bit is 0
    counts from 2036 (D-RCTP-19)."""
    seconds, fraction = value >> 32, value & 0xFFFFFFFF
    if not seconds & 0x80000000:
        seconds += 1 << 32
    return datetime.fromtimestamp(seconds - _NTP_TO_UNIX + fraction / 2**32, UTC)


class NTPTimestampField(Field[int, int]):
    """64-bit NTP time: seconds and a binary fraction (RFC 5905), shown as UTC."""

    def __init__(self, name: str, default: int) -> None:
        super().__init__(name, default, "!Q")

    def i2repr(self, pkt: Packet | None, x: int) -> str:
        if x is None:
            return "None"
        try:
            when = ntp_to_datetime(x).strftime("%Y-%m-%d %H:%M:%S.%f UTC")
        except (OverflowError, OSError, ValueError):
            when = "?"
        return f"0x{x:016x} ({when})"


# -- data stream payloads ------------------------------------------------------------------------


def flow_body_fits(body: bytes) -> bool:
    """A FLOW body with the layout of D-RCTP-22 for its message and operation (R-RCTP-52)."""
    if len(body) < 4:
        return False
    message, operation = body[0], body[1]
    if message == 2:
        return len(body) == 5 and body[4] in RCTP_NACK_REASONS
    if message == 0 and operation not in RCTP_FLOW_OPERATIONS:
        return True  # a request this side does not know: answered NACK 1
    size = RCTP_FLOW_FIELDS.get((message, operation))
    if size is None or len(body) != 4 + size:
        return False
    return operation == 1 or body[4] in RCTP_DIRECTIONS


class RCTPPayload(Packet):
    """A payload of a type this side does not know, skipped by its length (R-RCTP-51)."""

    name = "RCTP payload"
    #  0                   1                   2                   3
    #  0 1 2 3 4 5 6 7 8 9 0 1 2 3 4 5 6 7 8 9 0 1 2 3 4 5 6 7 8 9 0 1
    # +-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+
    # |  payload type |   stream id   |          body length          |
    # +-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+
    # |                  body (body length bytes) ...                 |
    fields_desc = [  # noqa: RUF012 (scapy reads the class attribute)
        ByteEnumField("type", 0, RCTP_PAYLOAD_TYPES),
        ByteField("stream", 0),
        ShortField("length", None),
        StrLenField("body", b"", length_from=lambda pkt: pkt.length),
    ]

    @classmethod
    def dispatch_hook(cls, _pkt: bytes | None = None, *args: Any, **kargs: Any) -> type[Packet]:
        if not _pkt or cls is not RCTPPayload:
            return cls
        if len(_pkt) < 4 or 4 + struct.unpack_from("!H", _pkt, 2)[0] > len(_pkt):
            return conf.raw_layer  # framing broken (R-RCTP-39)
        kind = _pkt[0]
        if kind == 1:
            return RCTPDataPayload
        if kind == 2:
            length = struct.unpack_from("!H", _pkt, 2)[0]
            if flow_body_fits(_pkt[4 : 4 + length]):
                return RCTPFlowPayload
            return RCTPMalformedFlowPayload
        return cls

    def post_build(self, pkt: bytes, pay: bytes) -> bytes:
        if self.length is None:
            pkt = pkt[:2] + struct.pack("!H", len(pkt) - 4) + pkt[4:]
        return pkt + pay

    def extract_padding(self, s: bytes) -> tuple[bytes, bytes]:
        return b"", s

    def mysummary(self) -> str:
        return f"type {self.type} s{self.stream} {len(self.body or b'')}B"


class RCTPDataPayload(RCTPPayload):
    """D-RCTP-20: a stream's values, in the binary value format of its RCML access."""

    name = "RCTP DATA payload"
    fields_desc = [  # noqa: RUF012 (scapy reads the class attribute)
        ByteEnumField("type", 1, RCTP_PAYLOAD_TYPES),
        ByteField("stream", 1),
        ShortField("length", None),
        StrLenField("data", b"", length_from=lambda pkt: pkt.length),
    ]

    def mysummary(self) -> str:
        return f"DATA s{self.stream} {len(self.data or b'')}B"


class _MicrosecondsField(IntField):
    """An interval or a timeout: unsigned 32-bit microseconds (D-RCTP-22)."""

    def i2repr(self, pkt: Packet | None, x: int) -> str:
        return f"{x} us" if x is not None else "None"


def _flow(*cells: tuple[int, int]) -> Any:
    """A FLOW field's condition: the (message, operation) pairs that carry it."""
    wanted = frozenset(cells)
    return lambda pkt: (pkt.getfieldval("message"), pkt.getfieldval("operation")) in wanted


_DIRECTED = tuple((m, o) for m in (0, 1) for o in (2, 3, 4, 5))


class RCTPFlowPayload(RCTPPayload):
    """D-RCTP-22: flow control; stream 0 concerns the session (a heartbeat)."""

    name = "RCTP FLOW payload"
    # | type = 2      |   stream id   |          body length          |
    # +-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+
    # |    message    |   operation   |          request id           |
    # +-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+
    # | heartbeat: T1 (64-bit NTP); its ACK: T1, T2, T3               |
    # | get/set: direction (8) [, interval or timeout (32, µs)]       |
    # | NACK: reason (8)                                              |
    fields_desc = [  # noqa: RUF012 (scapy reads the class attribute)
        ByteEnumField("type", 2, RCTP_PAYLOAD_TYPES),
        ByteField("stream", 0),
        ShortField("length", None),
        ByteEnumField("message", 0, RCTP_FLOW_MESSAGES),
        ByteEnumField("operation", 1, RCTP_FLOW_OPERATIONS),
        ShortField("request_id", 0),
        ConditionalField(NTPTimestampField("t1", 0), _flow((0, 1), (1, 1))),
        ConditionalField(NTPTimestampField("t2", 0), _flow((1, 1))),
        ConditionalField(NTPTimestampField("t3", 0), _flow((1, 1))),
        ConditionalField(ByteEnumField("data_direction", 1, RCTP_DIRECTIONS), _flow(*_DIRECTED)),
        ConditionalField(_MicrosecondsField("interval", 0), _flow((1, 2), (0, 3), (1, 3))),
        ConditionalField(_MicrosecondsField("timeout", 0), _flow((1, 4), (0, 5), (1, 5))),
        ConditionalField(ByteEnumField("reason", 1, RCTP_NACK_REASONS), lambda p: p.message == 2),
        ConditionalField(
            StrLenField("request_fields", b"", length_from=lambda pkt: (pkt.length or 4) - 4),
            lambda p: p.message == 0 and p.operation not in RCTP_FLOW_OPERATIONS,
        ),
    ]

    def mysummary(self) -> str:
        message = RCTP_FLOW_MESSAGES.get(self.message, str(self.message))
        operation = RCTP_FLOW_OPERATIONS.get(self.operation, f"operation {self.operation}")
        return f"FLOW {message} {operation} #{self.request_id}"


class RCTPMalformedFlowPayload(RCTPPayload):
    """A FLOW body that breaks its layout (R-RCTP-52): the packet's other payloads still count."""

    name = "RCTP FLOW payload (malformed)"
    fields_desc = [  # noqa: RUF012 (scapy reads the class attribute)
        ByteEnumField("type", 2, RCTP_PAYLOAD_TYPES),
        ByteField("stream", 0),
        ShortField("length", None),
        StrLenField("body", b"", length_from=lambda pkt: pkt.length),
    ]

    def mysummary(self) -> str:
        return f"FLOW malformed {len(self.body or b'')}B"


class RCTPStream(Packet):
    """A data-stream packet: one UDP datagram (D-RCTP-19)."""

    name = "RCTP data stream"
    #  0                   1                   2                   3
    #  0 1 2 3 4 5 6 7 8 9 0 1 2 3 4 5 6 7 8 9 0 1 2 3 4 5 6 7 8 9 0 1
    # +-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+
    # |  version = 2  | payload count |        sequence number        |
    # +-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+
    # |                          session tag                          |
    # +-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+
    # |                  timestamp, seconds (NTP era)                 |
    # +-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+
    # |                  timestamp, fraction of a second              |
    # +-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+
    # |  payload type |   stream id   |          body length          |
    # +-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+
    # |                  body (body length bytes) ...                 |
    # +-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+-+
    # |  next payload: type, stream id, length, body ...              |
    fields_desc = [  # noqa: RUF012 (scapy reads the class attribute)
        ByteField("version", RCTP_STREAM_VERSION),
        FieldLenField("count", None, count_of="payloads", fmt="B"),
        ShortField("seq", 0),
        XIntField("tag", 0),
        NTPTimestampField("timestamp", 0),
        PacketListField("payloads", [], RCTPPayload, count_from=lambda pkt: pkt.count),
    ]

    @classmethod
    def dispatch_hook(cls, _pkt: bytes | None = None, *args: Any, **kargs: Any) -> type[Packet]:
        if _pkt is not None and len(_pkt) < 16:
            return conf.raw_layer  # a header cut short
        return cls

    def mysummary(self) -> str:
        return self.describe()

    def describe(self) -> str:
        """The sequence number, the tag and each payload's type and stream, on one line."""
        payloads = ", ".join(str(p.mysummary()) or "Raw" for p in self.payloads)
        return f"RCTP-data seq={self.seq} tag={self.tag:08x} {payloads}"


# -- bindings ------------------------------------------------------------------------------------


def bind_port(port: int, control: bool = True, data: bool = True) -> None:
    """Dissect TCP `port` as the control connection and UDP `port` as the data stream (whose
    ports SETUP's `Transport` negotiates, D-RCTP-18), in either direction."""
    if control:
        bind_bottom_up(TCP, RCTP, sport=port)
        bind_bottom_up(TCP, RCTP, dport=port)
    if data:
        bind_bottom_up(UDP, RCTPStream, sport=port)
        bind_bottom_up(UDP, RCTPStream, dport=port)


bind_port(RCTP_PORT)
bind_layers(TCP, RCTP, sport=RCTP_PORT, dport=RCTP_PORT)
bind_top_down(TCP, RCTPRequest, sport=RCTP_PORT, dport=RCTP_PORT)
bind_top_down(TCP, RCTPResponse, sport=RCTP_PORT, dport=RCTP_PORT)
bind_layers(UDP, RCTPStream, sport=RCTP_PORT, dport=RCTP_PORT)
