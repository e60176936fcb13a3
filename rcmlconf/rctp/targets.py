"""Request-targets (D-RCTP-7): `*`, `/`, or a node path with percent-encoded segments."""

from __future__ import annotations

import re
from dataclasses import dataclass
from functools import lru_cache
from urllib.parse import quote, unquote_to_bytes

from rcmlconf.errors import ValueTextError
from rcmlconf.markup.lexical import is_name

# RFC 3986 pchar: unreserved, pct-encoded, sub-delims, ":" and "@".
_SEGMENT = re.compile(r"(?:[A-Za-z0-9\-._~!$&'()*+,;=:@]|%[0-9A-Fa-f]{2})+")
_SAFE = "-._~!$&'()*+,;=:@"

STAR = "*"
ROOT = "/"


@dataclass(frozen=True, slots=True)
class Target:
    #: `*` for the session, `/` for the whole tree, else a node path, decoded (D-RCML-3).
    path: str

    @property
    def is_session(self) -> bool:
        return self.path == STAR

    @property
    def is_node(self) -> bool:
        return self.path not in (STAR, ROOT)


@lru_cache(maxsize=1024)  # a robot's clients name the same few targets again and again
def parse_target(text: str) -> Target:
    if text in (STAR, ROOT):
        return Target(text)
    if not text.startswith("/"):
        raise ValueTextError(f"{text[:40]!r} is neither *, / nor a path starting with /")
    names = []
    for segment in text[1:].split("/"):
        if _SEGMENT.fullmatch(segment) is None:
            raise ValueTextError(f"{segment[:40]!r} is not a percent-encoded path segment")
        try:
            name = unquote_to_bytes(segment).decode("utf-8")
        except UnicodeDecodeError:
            raise ValueTextError(f"{segment[:40]!r} is not UTF-8 once decoded") from None
        if not is_name(name):
            raise ValueTextError(f"{name[:40]!r} is not an XML Name")
        names.append(name)
    return Target("/" + "/".join(names))


def format_target(path: str) -> str:
    """The wire form of `*`, `/` or a node path."""
    if path in (STAR, ROOT):
        return path
    return "/" + "/".join(quote(name, safe=_SAFE) for name in path[1:].split("/"))
