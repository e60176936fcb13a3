"""RCTP/2.0 control messages: framing, limits and the small grammars of specs/rctp-2.0.md §2."""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from urllib.parse import unquote_to_bytes

import bugs
from rcml import is_xml_name

VERSION = "RCTP/2.0"
MAX_START_LINE = 4096
MAX_HEADER_LINE = 4096
MAX_HEADER_SECTION = 16384
MAX_FIELDS = 64
MAX_BODY = 4194304
ONCE = ("cseq", "session", "content-length", "content-type", "nodes", "transport")
METHODS = ("CONNECT", "ACQUIRE", "RELEASE", "READ", "WRITE", "SETUP", "GO", "PAUSE", "STOP", "BYE")
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

_TOKEN = re.compile(rb"[!#$%&'*+\-.^_`|~0-9A-Za-z]+")
_TARGET_CHARS = re.compile(rb"[\x21-\x7e\x80-\xff]+")  # its syntax is checked later
_VALUE_BAD = re.compile(rb"[\x00-\x08\x0a-\x1f\x7f]")
# a CR followed by a byte other than LF; a CR last in the buffer may yet be a CRLF
_BARE_CR = re.compile(rb"\r[^\n]")
# the first line end that is not CRLF: a bare LF, or a CR followed by another byte
_BARE_END = re.compile(rb"(?<!\r)\n|\r(?=[^\n])")
BARE_LF = "a line ending in a bare LF"
BARE_CR = "a CR not followed by LF"
# D-RCTP-30: "RCTP/2.0" is case-sensitive, but `rctp/2.0` parses as another version (505)
_OTHER_VERSION = re.compile(r"RCTP/[0-9]+\.[0-9]+", re.ASCII | re.IGNORECASE)
_STATUS = re.compile(rb"RCTP/2\.0 ([0-9]{3}) [\t\x20-\x7e\x80-\xff]*")
_PCHARS = re.compile(r"(?:[A-Za-z0-9\-._~!$&'()*+,;=:@]|%[0-9A-Fa-f]{2})+")
_DIGITS = re.compile(r"[0-9]+")
SESSION_ID = re.compile(r"[A-Za-z0-9$\-_.+]{8,64}")
_SESSION_TIMEOUT = re.compile(r"[ \t]*timeout=[0-9]{1,5}", re.ASCII | re.IGNORECASE)
_ASCII_LOWER = str.maketrans("ABCDEFGHIJKLMNOPQRSTUVWXYZ", "abcdefghijklmnopqrstuvwxyz")


def ascii_lower(text: str) -> str:
    """D-RCTP-30: the grammar's tokens are compared without regard to ASCII letter case only."""
    return text.translate(_ASCII_LOWER)


class FrameError(Exception):
    """A message that cannot be framed: answered (if a request) with status, then the close."""

    def __init__(self, status: int, why: str, cseq: int | None = None, response: bool = False):
        super().__init__(why)
        self.status, self.cseq, self.response = status, cseq, response


@dataclass
class Message:
    start: str  # the start line
    request: bool
    method: str = ""
    target: str = ""
    version: str = ""
    status: int = 0
    fields: list[tuple[str, str]] = field(default_factory=list)  # (lower-case name, value)
    body: bytes = b""
    has_length: bool = False

    def all(self, name: str) -> list[str]:
        return [v for k, v in self.fields if k == name]

    def one(self, name: str) -> str | None:
        values = self.all(name)
        return values[0] if values else None


class Reader:
    """Frames messages out of a byte stream; buffers at most one message within the limits."""

    def __init__(self, start_limit: int = MAX_START_LINE) -> None:
        self.start_limit = start_limit  # a start line's bytes, without its CRLF
        # the bug repeated-field-acquired: twin Content-Length values taken as one
        self.twin_lengths_ok = False
        self.buf = bytearray()
        self._head: Message | None = None
        self._need = 0

    def feed(self, data: bytes) -> None:
        self.buf += data

    def next(self) -> Message | None:
        """The next whole message, None when more bytes are needed; raises FrameError."""
        if self._head is None:
            end = self.buf.find(b"\r\n\r\n")
            if end < 0:
                self._check_partial()
                return None
            head = bytes(self.buf[: end + 2])
            self._head, self._need = _parse_head(head, self.start_limit, self.twin_lengths_ok)
            del self.buf[: end + 4]
        if len(self.buf) < self._need:
            return None
        msg, self._head = self._head, None
        msg.body = bytes(self.buf[: self._need])
        del self.buf[: self._need]
        return msg

    def _check_partial(self) -> None:
        """Limits, bare LFs and bare CRs found before the header section is complete.

        A bare CR is known as soon as the byte after it comes, so it is answered then: the
        bytes before it are checked first (an earlier error wins), then the CR itself."""
        bare_cr = _BARE_CR.search(self.buf)
        if bare_cr is None:
            self._check_lines(self.buf)
            return
        self._check_lines(self.buf[: bare_cr.start()])
        raise FrameError(400, BARE_CR, response=self.buf.startswith(b"RCTP/"))

    def _check_lines(self, buf: bytearray) -> None:
        """Limits and bare line feeds in the lines of an incomplete header section."""
        first = buf.find(b"\n")
        response = buf.startswith(b"RCTP/")
        if first < 0:
            if len(buf) > self.start_limit + 1:
                raise FrameError(414, "start line above 4,096 bytes", response=response)
            return
        if first == 0 or buf[first - 1] != 0x0D:
            raise FrameError(400, BARE_LF, response=response)
        if first - 1 > self.start_limit:
            raise FrameError(414, "start line above 4,096 bytes", response=response)
        pos, fields, total = first + 1, 0, 0
        while True:
            nl = buf.find(b"\n", pos)
            if nl < 0:
                if (
                    len(buf) - pos > MAX_HEADER_LINE + 1
                    or total + len(buf) - pos > MAX_HEADER_SECTION
                ):
                    raise FrameError(
                        431, "header line or section above the limits", response=response
                    )
                return
            if nl == pos or buf[nl - 1] != 0x0D:
                raise FrameError(400, BARE_LF, response=response)
            total += nl + 1 - pos
            fields += 1
            if nl - 1 - pos > MAX_HEADER_LINE or total > MAX_HEADER_SECTION or fields > MAX_FIELDS:
                raise FrameError(431, "header line or section above the limits", response=response)
            pos = nl + 1


def _parse_head(
    head: bytes, start_limit: int = MAX_START_LINE, twin_lengths_ok: bool = False
) -> tuple[Message, int]:
    lines = head.split(b"\r\n")[:-1]
    start = lines[0]
    response = start.startswith(b"RCTP/")
    bad = _BARE_END.search(head)
    if bad:
        why = BARE_LF if bad.group() == b"\n" else BARE_CR
        raise FrameError(400, why, response=response)
    if len(start) > start_limit:
        raise FrameError(414, "start line above 4,096 bytes", response=response)
    header_lines = lines[1:]
    section = sum(len(x) + 2 for x in header_lines)
    if len(header_lines) > MAX_FIELDS or section > MAX_HEADER_SECTION:
        raise FrameError(431, "header section above the limits", response=response)
    if any(len(x) > MAX_HEADER_LINE for x in header_lines):
        raise FrameError(431, "header line above 4,096 bytes", response=response)
    fields: list[tuple[str, str]] = []
    for line in header_lines:
        if line[:1] in (b" ", b"\t"):
            raise FrameError(400, "obsolete line folding", response=response)
        name, colon, value = line.partition(b":")
        if not colon or not _TOKEN.fullmatch(name):
            raise FrameError(400, f"bad header line {line[:60]!r}", response=response)
        value = value.strip(b" \t")
        if _VALUE_BAD.search(value) or b"\r" in value:
            raise FrameError(400, "control character in a field value", response=response)
        fields.append((name.decode("ascii").lower(), value.decode("latin-1")))
    cseq = _cseq_of(fields)
    if any(k == "transfer-encoding" for k, _ in fields):
        raise FrameError(400, "Transfer-Encoding is not used", cseq, response)
    lengths = [v for k, v in fields if k == "content-length"]
    if len(set(lengths)) > 1:
        raise FrameError(400, "Content-Length fields disagree", cseq, response)
    need = 0
    if lengths:
        text = lengths[0]
        if bugs.on("content-length-sign") and text[:1] in ("+", "-"):
            # the bug: the sign is taken by int(), and a negative length reaches the buffer
            bugs.crash(ValueError(f"negative or signed body length {text!r}"))
        if len(lengths) > 1 and not twin_lengths_ok:
            # D-RCTP-10: twins, even equal, cannot be framed (RFC 9112 §6.3 may take them as one)
            raise FrameError(400, "Content-Length given more than once", cseq, response)
        if not _DIGITS.fullmatch(text):
            raise FrameError(400, "bad Content-Length", cseq, response)
        need = int(text)
        if need > MAX_BODY:
            raise FrameError(413, "Content-Length above 4,194,304", cseq, response)
        if len(text) > 10:
            raise FrameError(400, "bad Content-Length", cseq, response)
    if response:
        match = _STATUS.fullmatch(start)
        if not match:
            raise FrameError(400, "bad status line", response=True)
        msg = Message(start.decode("latin-1"), False, status=int(match.group(1)), fields=fields)
    else:
        parts = start.split(b" ")
        if (
            len(parts) != 3
            or not _TOKEN.fullmatch(parts[0])
            or not _TARGET_CHARS.fullmatch(parts[1])
        ):
            raise FrameError(400, "bad request line", cseq)
        method, target, version = (p.decode("latin-1") for p in parts)
        if version != VERSION and not _OTHER_VERSION.fullmatch(version):
            raise FrameError(400, "bad version", cseq)
        msg = Message(start.decode("latin-1"), True, method, target, version, fields=fields)
    msg.has_length = bool(any(k == "content-length" for k, _ in fields))
    return msg, need


def _cseq_of(fields: list[tuple[str, str]]) -> int | None:
    values = [v for k, v in fields if k == "cseq"]
    return parse_cseq(values[0]) if len(values) == 1 else None


def parse_cseq(text: str) -> int | None:
    if not re.fullmatch(r"[0-9]{1,10}", text):
        return None
    value = int(text)
    return value if 1 <= value <= 2147483647 else None


def parse_target(target: str) -> str | None:
    """A request-target as a decoded path, "*" or "/"; None when it breaks D-RCTP-7."""
    if target in ("*", "/"):
        return target
    if not target.startswith("/"):
        return None
    names = []
    for segment in target[1:].split("/"):
        name = decode_name(segment)
        if name is None:
            return None
        names.append(name)
    return "/" + "/".join(names)


def decode_name(segment: str) -> str | None:
    """A percent-encoded path segment as a node name, None unless it is an XML Name."""
    if not _PCHARS.fullmatch(segment):
        return None
    try:
        name = unquote_to_bytes(segment).decode("utf-8")
    except UnicodeDecodeError:
        return None
    return name if is_xml_name(name) else None


def parse_session(text: str) -> str | None:
    """The session-id of a Session field (a timeout parameter may follow).

    D-RCTP-30: `timeout` is read in any letter case (`TimeOut=60`, `; TIMEOUT=60`);
    the session-id itself is compared exactly by the caller."""
    sid, _, rest = text.partition(";")
    if rest and not _SESSION_TIMEOUT.fullmatch(rest):
        return None
    return sid if SESSION_ID.fullmatch(sid) else None


def parse_transport(text: str) -> dict[str, str] | None:
    """A Transport field as its parameters; None when it breaks the grammar of §2.1."""
    parts = text.split(";")
    if ascii_lower(parts[0].strip(" \t")) != "udp":
        return None
    params: dict[str, str] = {}
    for part in parts[1:]:
        key, eq, value = part.strip(" \t").partition("=")
        key, value = ascii_lower(key), ascii_lower(value)  # D-RCTP-30: names and modes
        if not eq or key in params:
            return None
        if key in ("client_port", "server_port"):
            if not re.fullmatch(r"[0-9]{1,5}", value) or not 1 <= int(value) <= 65535:
                return None
        elif key == "tag":
            if not re.fullmatch(r"[0-9a-f]{8}", value):
                return None
        elif key == "mode":
            if value not in ("read", "write", "both"):
                return None
        elif key == "stream":
            if not re.fullmatch(r"[0-9]{1,3}", value):
                return None
        else:
            return None
        params[key] = value
    return params


def build(start: str, headers: list[tuple[str, str]], body: bytes = b"", ctype: str = "") -> bytes:
    lines = [start, *(f"{k}: {v}" for k, v in headers)]
    if body:
        lines += [f"Content-Type: {ctype}", f"Content-Length: {len(body)}"]
    return ("\r\n".join(lines) + "\r\n\r\n").encode("utf-8") + body
