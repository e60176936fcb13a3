"""RCTP/2.0 control messages: an incremental, bounded parser and builders (specs/rctp-2.0.md
§2, D-RCTP-4 to D-RCTP-10)."""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from urllib.parse import quote

from rcml import is_xml_name

VERSION = "RCTP/2.0"
MAX_START = 4096  # D-RCTP-9, without the CRLF
MAX_LINE = 4096
MAX_SECTION = 16384
MAX_FIELDS = 64
MAX_BODY = 4194304
MAX_CSEQ = 2147483647
ONCE = ("cseq", "session", "content-length", "content-type", "nodes", "transport")
METHODS = ("CONNECT", "ACQUIRE", "RELEASE", "READ", "WRITE", "SETUP", "GO", "PAUSE", "STOP", "BYE")
VALUES = "application/rctp-values"

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
_VALUE = re.compile(rb"([\x21-\x7e\x80-\xff]([\x20\x09\x21-\x7e\x80-\xff]*[\x21-\x7e\x80-\xff])?)?")
_STATUS = re.compile(rb"(RCTP/[0-9]+\.[0-9]+) ([0-9]{3}) ([\x09\x20-\x7e\x80-\xff]*)")
_VERSION = re.compile(rb"RCTP/[0-9]+\.[0-9]+")
# a CR followed by a byte other than LF; a CR last in the buffer may yet be a CRLF
_BARE_CR = re.compile(rb"\r[^\n]")
_PCHAR = re.compile(r"([A-Za-z0-9\-._~!$&'()*+,;=:@]|%[0-9A-Fa-f]{2})+")


@dataclass
class Message:
    request: bool
    method: str = ""
    target: str = ""
    version: str = VERSION
    status: int = 0
    reason: str = ""
    fields: list[tuple[str, str]] = field(default_factory=list)
    body: bytes = b""

    def all(self, name: str) -> list[str]:
        low = name.lower()
        return [v for k, v in self.fields if k.lower() == low]

    def get(self, name: str) -> str | None:
        found = self.all(name)
        return found[0] if found else None

    def cseq(self) -> int | None:
        """The CSeq when there is exactly one and it is valid (D-RCTP-6, grammar)."""
        found = self.all("CSeq")
        if len(found) != 1 or not re.fullmatch(r"[0-9]{1,10}", found[0]):
            return None
        n = int(found[0])
        return n if 1 <= n <= MAX_CSEQ else None

    def summary(self) -> str:
        if self.request:
            return f"{self.method} {self.target}"
        return f"{self.status} {self.reason}"


class FrameError(Exception):
    """A message that cannot be framed: `status` answers a request (None for a response)."""

    def __init__(self, status: int | None, why: str, cseq: int | None = None) -> None:
        super().__init__(why)
        self.status = status
        self.cseq = cseq


class Parser:
    """Bytes in, messages out; never holds more than one message's limits (R-RCTP-16)."""

    def __init__(self, line_limit: int = MAX_LINE) -> None:
        self._buf = bytearray()
        self._line_limit = line_limit
        self._msg: Message | None = None
        self._section = 0
        self._need: int | None = None  # body bytes awaited

    def feed(self, data: bytes) -> None:
        self._buf += data

    def discard(self) -> None:
        """Forget everything received so far (what a careless receiver does after an error)."""
        self._buf.clear()
        self._msg, self._need = None, None

    def _fail(self, status: int, why: str) -> FrameError:
        msg = self._msg
        if msg is not None and not msg.request:
            return FrameError(None, why)
        if msg is None and self._buf.startswith(b"RCTP/"):
            return FrameError(None, why)
        cseq = msg.cseq() if msg is not None else None
        return FrameError(status, why, cseq)

    def _line(self, limit: int, code: int) -> bytes | None:
        """The next line without its CRLF; None until it is whole. A bare CR is an error as
        soon as the byte after it comes, without waiting for an LF. The line stays in the
        buffer until it is good, so that `_fail` still sees a status line's `RCTP/`."""
        end = self._buf.find(b"\n", 0, limit + 2)
        if end < 0:
            if _BARE_CR.search(self._buf, 0, limit + 2):
                raise self._fail(400, "bare CR")
            if len(self._buf) >= limit + 2:
                raise self._fail(code, "line over the limit")
            return None
        raw = bytes(self._buf[:end])
        ended = raw.endswith(b"\r")
        if b"\r" in (raw[:-1] if ended else raw):
            raise self._fail(400, "bare CR")
        if not ended:
            raise self._fail(400, "bare LF")
        raw = raw[:-1]
        if len(raw) > limit:
            raise self._fail(code, "line over the limit")
        del self._buf[: end + 1]
        self._section += len(raw) + 2
        return raw

    def next(self) -> Message | None:
        """The next whole message, None until one is whole; FrameError when one cannot be."""
        if self._msg is None:
            raw = self._line(MAX_START, 414)
            if raw is None:
                return None
            self._msg = self._start(raw)
            self._section = 0
        msg = self._msg
        while self._need is None:
            raw = self._line(self._line_limit, 431)
            if raw is None:
                return None
            if raw == b"":
                self._need = self._framing(msg)
                break
            if self._section > MAX_SECTION or len(msg.fields) >= MAX_FIELDS:
                raise self._fail(431, "header section over the limit")
            if raw[:1] in (b" ", b"\t"):
                raise self._fail(400, "obsolete line folding")
            name, sep, value = raw.partition(b":")
            value = value.strip(b" \t")
            if not sep or not _TOKEN.fullmatch(name) or not _VALUE.fullmatch(value):
                raise self._fail(400, "a header field that does not parse")
            msg.fields.append((name.decode("ascii"), value.decode("latin-1")))
        if len(self._buf) < self._need:
            return None
        msg.body = bytes(self._buf[: self._need])
        del self._buf[: self._need]
        self._msg, self._need = None, None
        return msg

    def _start(self, raw: bytes) -> Message:
        if raw.startswith(b"RCTP/"):
            m = _STATUS.fullmatch(raw)
            if not m:
                raise FrameError(None, "a status line that does not parse")
            return Message(
                False,
                version=m.group(1).decode(),
                status=int(m.group(2)),
                reason=m.group(3).decode("latin-1"),
            )
        parts = raw.split(b" ")
        if len(parts) != 3 or not _TOKEN.fullmatch(parts[0]) or not parts[1]:
            raise FrameError(400, "a request line that does not parse")
        if not _VERSION.fullmatch(parts[2]):
            raise FrameError(400, "not an RCTP version")
        return Message(
            True,
            method=parts[0].decode("ascii"),
            target=parts[1].decode("latin-1"),
            version=parts[2].decode("ascii"),
        )

    def _framing(self, msg: Message) -> int:
        if msg.all("Transfer-Encoding"):
            raise self._fail(400, "Transfer-Encoding")
        lengths = msg.all("Content-Length")
        if not lengths:
            return 0
        if len(lengths) > 1:  # D-RCTP-10: twins cannot be framed, even with the same value
            raise self._fail(400, "Content-Length given more than once")
        if not re.fullmatch(r"[0-9]{1,10}", lengths[0]):
            raise self._fail(400, "bad Content-Length")
        if int(lengths[0]) > MAX_BODY:
            raise self._fail(413, "Content-Length over the limit")
        return int(lengths[0])


def decode_target(target: str) -> list[str] | None:
    """A request-target's segments, [] for `/`; None when it is not `*`, `/` or a path of
    percent-encoded XML Names (D-RCTP-7)."""
    if target == "/":
        return []
    if not target.startswith("/"):
        return None
    segments = []
    for raw in target[1:].split("/"):
        if not _PCHAR.fullmatch(raw):
            return None
        try:
            decoded = _unquote(raw).decode("utf-8")
        except (ValueError, UnicodeDecodeError):
            return None
        if not is_xml_name(decoded):
            return None
        segments.append(decoded)
    return segments


def _unquote(raw: str) -> bytes:
    out = bytearray()
    i = 0
    while i < len(raw):
        if raw[i] == "%":
            out.append(int(raw[i + 1 : i + 3], 16))
            i += 3
        else:
            out += raw[i].encode("ascii")
            i += 1
    return bytes(out)


def encode_segment(name: str) -> str:
    return quote(name, safe=":@!$&'()*+,;=-._~")


def encode_path(path: str) -> str:
    if path in ("/", "*"):
        return path
    return "".join("/" + encode_segment(s) for s in path.split("/")[1:])


def build(start: str, fields: list[tuple[str, str]], body: bytes = b"", eol_of: str = "") -> bytes:
    """A message; `eol_of` names a field whose line ends in a bare LF (a fault)."""
    out = [start.encode("latin-1") + b"\r\n"]
    for name, value in fields:
        eol = b"\n" if name == eol_of else b"\r\n"
        out.append(name.encode("ascii") + b": " + value.encode("latin-1") + eol)
    out.append(b"\r\n")
    return b"".join(out) + body


def response(status: int, fields: list[tuple[str, str]], body: bytes = b"") -> bytes:
    return build(f"{VERSION} {status} {REASONS.get(status, 'Error')}", fields, body)
