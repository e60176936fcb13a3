"""The values of RCTP/2.0 header fields (specs/rctp-2.0.md §2.1, §2.2): read and written.

Each reader takes the field's text and returns its value or raises `ValueTextError`; the
connection answers a bad field with 400.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass
from urllib.parse import quote, unquote

from rcmlconf.errors import ValueTextError
from rcmlconf.markup.lexical import is_name

MAX_CSEQ = 2**31 - 1
DEFAULT_SESSION_TIMEOUT = 60

_CSEQ = re.compile(r"[0-9]{1,10}")
#: `timeout` in any letter case (D-RCTP-30); the session ID exactly as given.
_SESSION = re.compile(r"([A-Za-z0-9$\-_.+]{8,64})(?:;[ \t]*(?ai:timeout)=([0-9]{1,5}))?")
_PORT = re.compile(r"[0-9]{1,5}")
_TAG = re.compile(r"[0-9A-Fa-f]{8}")
_STREAM = re.compile(r"[0-9]{1,3}")
_SAFE = "-._~!$&'()*+;=:@"


def same_token(given: str | None, token: str) -> bool:
    """Whether a field's `given` text is the grammar's `token` (a media type, `udp`, a Reason):
    compared without regard to ASCII letter case, as D-RCTP-30 says of everything the grammar
    spells out but the methods and the version."""
    return given is not None and given.isascii() and given.lower() == token.lower()


def parse_cseq(text: str) -> int:
    if _CSEQ.fullmatch(text) is None or not 1 <= int(text) <= MAX_CSEQ:
        raise ValueTextError(f"CSeq {text[:20]!r} is not a number from 1 to {MAX_CSEQ}")
    return int(text)


@dataclass(frozen=True, slots=True)
class SessionField:
    id: str
    #: Seconds; only in the answer to CONNECT (D-RCTP-11).
    timeout: int | None = None

    def __str__(self) -> str:
        return self.id if self.timeout is None else f"{self.id};timeout={self.timeout}"


def parse_session(text: str) -> SessionField:
    match = _SESSION.fullmatch(text)
    if match is None:
        raise ValueTextError(f"Session {text[:40]!r} is not id[;timeout=seconds]")
    timeout = match.group(2)
    return SessionField(match.group(1), int(timeout) if timeout is not None else None)


def parse_nodes(text: str) -> tuple[str, ...]:
    """D-RCTP-18, R-RCTP-30: data node names, each once, in canonical order."""
    names = tuple(unquote(part.strip(" \t"), errors="strict") for part in text.split(","))
    for name in names:
        if not is_name(name):
            raise ValueTextError(f"Nodes: {name[:40]!r} is not an XML Name")
    if list(names) != sorted(set(names)):
        raise ValueTextError("Nodes must list each node once, in canonical order (D-RCML-4)")
    return names


def format_nodes(names: Sequence[str]) -> str:
    return ", ".join(quote(name, safe=_SAFE) for name in sorted(names))


@dataclass(frozen=True, slots=True)
class Transport:
    """SETUP's `Transport` (D-RCTP-19); the server fills in the last three."""

    client_port: int | None = None
    mode: str = "read"
    server_port: int | None = None
    tag: int | None = None
    stream: int | None = None

    def __str__(self) -> str:
        parts = ["udp"]
        if self.client_port is not None:
            parts.append(f"client_port={self.client_port}")
        if self.server_port is not None:
            parts.append(f"server_port={self.server_port}")
        if self.tag is not None:
            parts.append(f"tag={self.tag:08x}")
        parts.append(f"mode={self.mode}")
        if self.stream is not None:
            parts.append(f"stream={self.stream}")
        return ";".join(parts)


_MODES = ("read", "write", "both")


def parse_transport(text: str) -> Transport:
    # `udp`, the parameter names and the modes in any letter case (D-RCTP-30).
    protocol, *params = (part.strip(" \t") for part in text.split(";"))
    if not same_token(protocol, "udp"):
        raise ValueTextError(f"Transport {protocol[:20]!r}: RCTP/2.0's data stream is udp")
    values: dict[str, str] = {}
    for param in params:
        key, equals, value = param.partition("=")
        key = key.lower() if key.isascii() else key
        if not equals or key in values:
            raise ValueTextError(f"Transport parameter {param[:30]!r} is not key=value, once")
        values[key] = value
    unknown = set(values) - {"client_port", "server_port", "tag", "stream", "mode"}
    if unknown:
        raise ValueTextError(f"unknown Transport parameter {sorted(unknown)[0]!r}")
    mode = values.get("mode", "read")
    mode = mode.lower() if mode.isascii() else mode
    if mode not in _MODES:
        raise ValueTextError(f"Transport mode {mode[:20]!r} is not read, write or both")
    tag = values.get("tag")
    if tag is not None and _TAG.fullmatch(tag) is None:
        raise ValueTextError("Transport tag is 8 hexadecimal digits")
    return Transport(
        client_port=_bounded(values.get("client_port"), _PORT, 1, 65535, "client_port"),
        mode=mode,
        server_port=_bounded(values.get("server_port"), _PORT, 1, 65535, "server_port"),
        tag=int(tag, 16) if tag is not None else None,
        stream=_bounded(values.get("stream"), _STREAM, 1, 255, "stream"),
    )


def _bounded(text: str | None, form: re.Pattern[str], low: int, high: int, what: str) -> int | None:
    if text is None:
        return None
    if form.fullmatch(text) is None or not low <= int(text) <= high:
        raise ValueTextError(f"Transport {what} {text[:10]!r} is not from {low} to {high}")
    return int(text)
