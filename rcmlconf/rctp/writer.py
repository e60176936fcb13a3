"""Write RCTP/2.0 control messages (specs/rctp-2.0.md §2.1), refusing what the grammar refuses.

What this side sends is checked as strictly as what it receives: a conformance tool's own
messages must be beyond reproach. A message that breaks the grammar is a `LocalProtocolError`.
"""

from __future__ import annotations

import re

from rcmlconf.rctp.errors import LocalProtocolError
from rcmlconf.rctp.messages import Message, Request
from rcmlconf.rctp.reader import LIMITS

_TOKEN = re.compile(r"[!#$%&'*+\-.^_`|~0-9A-Za-z]+")
_TARGET = re.compile(r"[\x21-\x7e]+")
_VERSION = re.compile(r"RCTP/[0-9]+\.[0-9]+")
# A field value has no leading or trailing white space (RFC 9110 §5.5).
_FIELD_VALUE = re.compile(
    r"(?:[\x21-\x7e\x80-\xff](?:[\t\x20-\x7e\x80-\xff]*[\x21-\x7e\x80-\xff])?)?"
)
_REASON = re.compile(r"[\t\x20-\x7e\x80-\xff]*")


def write_message(message: Message) -> bytes:
    if isinstance(message, Request):
        if _TOKEN.fullmatch(message.method) is None:
            raise LocalProtocolError(f"method {message.method!r} is not a token")
        if _TARGET.fullmatch(message.target) is None:
            raise LocalProtocolError(f"target {message.target!r} is not percent-encoded ASCII")
        start = f"{message.method} {message.target} {message.version}"
    else:
        if not 100 <= message.status <= 999 or _REASON.fullmatch(message.reason) is None:
            raise LocalProtocolError(f"status {message.status} {message.reason!r} is malformed")
        start = f"{message.version} {message.status} {message.reason}"
    if _VERSION.fullmatch(message.version) is None:
        raise LocalProtocolError(f"version {message.version!r} is malformed")
    if len(start) > LIMITS.start_line:
        raise LocalProtocolError("start line above the limit of D-RCTP-9")
    lines = [start]
    length = None
    for name, value in message.headers:
        if _TOKEN.fullmatch(name) is None or _FIELD_VALUE.fullmatch(value) is None:
            raise LocalProtocolError(f"header field {name!r}: {value!r} is malformed")
        if name.lower() == "content-length":
            length = value
        lines.append(f"{name}: {value}")
    if (length or "0") != str(len(message.body)):
        raise LocalProtocolError(
            f"Content-Length {length} does not match the body's {len(message.body)} bytes"
        )
    lines.append("\r\n")
    return "\r\n".join(lines).encode("latin-1") + message.body
