"""The command line's URL, PATHs and --rcml, checked before anything is fetched or sent.

What RCTP/2.0 or the resolver could not carry is a usage error naming the input, not a failure
halfway through a session: a site path that is no request-target (D-RCTP-3, D-RCTP-7), a target
too long for a start line (D-RCTP-9), a host name no resolver takes (RFC 1035), an --rcml that is
neither a file name nor an http(s) URL. Long input is shown shortened, so that the error stays one
line a person can read.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from urllib.parse import urlsplit

from rcmlconf.errors import ValueTextError
from rcmlconf.rcml.url import RctpUrl, parse_rctp_url
from rcmlconf.rctp.reader import LIMITS
from rcmlconf.rctp.targets import format_target, parse_target
from rcmlconf.reference.client.files import is_http_url
from rcmlconf.wording import shorten

#: The longest request-target the client may send. Its longest methods are CONNECT, ACQUIRE and
#: RELEASE, and `METHOD SP target SP RCTP/2.0` is at most 4,096 bytes (D-RCTP-9).
MAX_TARGET = LIMITS.start_line - len("CONNECT  RCTP/2.0")
#: The longest URL the client takes, an RCTP start line's length (D-RCTP-9): CONNECT sends the
#: URL's path in one, so a longer URL is not one to connect to.
MAX_URL = LIMITS.start_line
_TARGET_LIMIT = (
    f"a request-target is at most {MAX_TARGET:,} bytes, so that the request's start line fits"
    f" in {LIMITS.start_line:,} (D-RCTP-9)"
)
#: A DNS name is at most 253 characters, each label 1 to 63 (RFC 1035 §2.3.4); the resolver
#: refuses any other before it asks anyone.
_MAX_HOST = 253
_LABEL = re.compile(r"[^.]{1,63}")
_CONTROLS = re.compile(r"[\x00-\x1f\x7f-\x9f]")


def check_url(text: str) -> RctpUrl:
    """The RCTP URL `text`, whose path CONNECT can carry and whose host can be looked up."""
    if len(text) > MAX_URL:
        raise ValueTextError(
            f"{shown(text)} is {len(text):,} characters long; the client takes URLs of at most"
            f" {MAX_URL:,}, the longest start line CONNECT may send the path in (D-RCTP-9)"
        )
    url = parse_rctp_url(text)
    try:
        site = parse_target(url.path)  # CONNECT's target is the site path (D-RCTP-3)
    except ValueTextError as exc:
        raise ValueTextError(f"{shown(text)}: its path is not a site path: {exc}") from None
    _fits(site.path, shown(text))
    if ":" not in url.host:  # not an IPv6 address, which parse_rctp_url checked
        labels = url.host.removesuffix(".").split(".")
        if len(url.host) > _MAX_HOST or not all(_LABEL.fullmatch(label) for label in labels):
            raise ValueTextError(
                f"{shown(text)}: host {shown(url.host)} is not a DNS name (at most"
                f" {_MAX_HOST} characters, dot-separated labels of 1 to 63, RFC 1035)"
            )
    return url


def check_path(text: str, parse: Callable[[str], str]) -> str:
    """A node path (`parse` says which kind) that fits in a request's start line."""
    if len(text) > MAX_TARGET:  # percent-encoding only lengthens it
        raise ValueTextError(f"{shown(text)} is {len(text):,} characters long; {_TARGET_LIMIT}")
    path = parse(text)
    _fits(path, shown(text))
    return path


def _fits(path: str, what: str) -> None:
    wire = len(format_target(path))
    if wire > MAX_TARGET:
        raise ValueTextError(f"{what} is {wire:,} bytes percent-encoded; {_TARGET_LIMIT}")


def check_rcml(text: str) -> str:
    """--rcml: a file name, or an http(s) URL with a host and, if it has one, a port."""
    if not text:
        raise ValueTextError("'' is empty: give the robot's RCML file or its http(s) URL")
    if _CONTROLS.search(text):
        # A file's name is shown whole where it fits a line: the part cut off may be the part
        # that holds the newline.
        named = repr(text) if len(text) <= 300 else shown(text)
        raise ValueTextError(f"{named} holds a control character")
    if is_http_url(text):
        check_http_url(text)
    return text


def check_http_url(text: str) -> str:
    """An http(s) URL with a host and, if it has one, a port."""
    if len(text) > MAX_URL:
        raise ValueTextError(f"{shown(text)} is {len(text):,} characters long; at most {MAX_URL:,}")
    if _CONTROLS.search(text):  # urlsplit would drop a newline without a word
        raise ValueTextError(f"{shown(text)} holds a control character")
    try:
        parts = urlsplit(text)
        if parts.port == 0 or not parts.hostname:  # reading the port checks it
            raise ValueError("no host and port to fetch from")
    except ValueError as exc:
        raise ValueTextError(f"{shown(text)} is not a URL to fetch: {exc}") from None
    return text


def shown(text: str) -> str:
    """`text` quoted, and shortened to fit a one-line message."""
    return repr(shorten(text, 60))
