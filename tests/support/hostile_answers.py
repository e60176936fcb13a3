"""Servers that answer out of place, each the embedded reference behind a `ControlProxy` that
spoils what it answers (D-RCTP-6, R-RCTP-3): every answer twice, an answer to no request, an
answer with another CSeq than its request's. What the harness reads must fail them all."""

from __future__ import annotations

import re
from collections.abc import Callable

from support.control_proxy import Address, ControlProxy

#: The answer of no request's that `unsolicited` sends after the answer to CONNECT.
STRAY = b"RCTP/2.0 200 OK\r\nCSeq: 4242\r\n\r\n"
#: How far `wrong_cseq` moves each answer's CSeq.
SHIFT = 100
_CSEQ = re.compile(rb"\r\nCSeq: ([0-9]+)\r\n")
_SESSION_TIMEOUT = re.compile(rb"\r\nSession: [^\r]*;timeout=", re.IGNORECASE)


def _answer(message: bytes) -> bool:
    return message.startswith(b"RCTP/")


def duplicate(message: bytes) -> bytes:
    """Every answer sent twice."""
    return message + message if _answer(message) else message


def unsolicited(message: bytes) -> bytes:
    """The answer to CONNECT (the one naming the session's timeout), then one to no request."""
    return message + STRAY if _answer(message) and _SESSION_TIMEOUT.search(message) else message


def wrong_cseq(message: bytes) -> bytes:
    """Every answer with its request's CSeq plus SHIFT."""
    if not _answer(message):
        return message
    return _CSEQ.sub(lambda m: b"\r\nCSeq: %d\r\n" % (int(m.group(1)) + SHIFT), message, count=1)


#: Each hostile server by name: the proxy in front of the reference server at an address.
HOSTILE: dict[str, Callable[[Address], ControlProxy]] = {
    name: (lambda upstream, spoil=spoil: ControlProxy(upstream, rewrite=spoil))
    for name, spoil in (
        ("duplicate", duplicate),
        ("unsolicited", unsolicited),
        ("wrong-cseq", wrong_cseq),
    )
}
