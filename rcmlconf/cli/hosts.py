"""Addresses as options take them: `HOST[:PORT]`, an IPv6 address in brackets (`[::1]:7330`).

A host is an IP address or a name a resolver could look up (RFC 1123 labels, IDNA for names that
are not ASCII); anything else (`::::`, `a b`, `a..b`) is refused as the option's value before
anything is sent, rather than failing later as "Name or service not known" in every case.
"""

from __future__ import annotations

import ipaddress
import re
from collections.abc import Callable
from typing import NoReturn

import click

from rcmlconf.wording import quoted

Address = tuple[str, int]

#: A label of a host name: letters, digits, hyphens (not first or last), 1 to 63 of them. `_` is
#: let in: container and service names have it, and resolvers look them up.
_LABEL = re.compile(r"(?!-)[A-Za-z0-9_-]{1,63}(?<!-)")
#: RFC 1035: a name is at most 253 characters written out.
_MOST_NAME = 253
_IPV6_HINT = "an IPv6 address with a port goes in brackets: [::1]:7330"


def host_problem(host: str) -> str | None:
    """Why `host` is neither an IP address nor a host name, or None when it is one."""
    if not host:
        return "has no host"
    try:
        ipaddress.ip_address(host)
        return None
    except ValueError:
        pass
    if ":" in host:
        return f"is neither an IP address nor a host name ({_IPV6_HINT})"
    try:
        name = host.encode("idna").decode("ascii").removesuffix(".")
    except UnicodeError:
        name = ""
    labels = name.split(".")
    if len(name) > _MOST_NAME or not all(_LABEL.fullmatch(label) for label in labels):
        return (
            "is neither an IP address nor a host name (dot-separated labels of 1 to 63 letters,"
            " digits and hyphens)"
        )
    if labels[-1].isdigit():
        return "is not an IPv4 address (four numbers 0 to 255) nor a host name"
    return None


def parse_address(text: str, default_port: int | None) -> Address:
    """`HOST[:PORT]` or `[IPv6][:PORT]` as a (host, port) pair; `default_port` None: the port
    must be given. click.BadParameter says what is wrong."""
    host, port = text, None
    if text.startswith("["):
        host, bracket, rest = text[1:].partition("]")
        if not bracket or (rest and not rest.startswith(":")):
            _fail(text, f"is not [IPv6]:PORT ({_IPV6_HINT})")
        if ":" not in host:
            _fail(text, "has no IPv6 address in its brackets")
        port = _port(rest[1:], text) if rest else None
    elif text.count(":") == 1:
        host, _, number = text.partition(":")
        port = _port(number, text)
    problem = host_problem(host)
    if problem is not None:
        _fail(text, problem)
    if port is None:
        if default_port is None:
            _fail(text, "names no port: HOST:PORT, the port 1 to 65535")
        port = default_port
    return host, port


def address_option(default_port: int | None) -> Callable[..., Address | None]:
    """A click callback: the option's `HOST[:PORT]` as an address, or a usage error naming it."""

    def convert(ctx: click.Context, param: click.Parameter, value: str | None) -> Address | None:
        return None if value is None else parse_address(value, default_port)

    return convert


def listen_option(host: str) -> Callable[..., Address | None]:
    """A click callback for `[HOST:]PORT`: a port alone listens on `host`."""

    def convert(ctx: click.Context, param: click.Parameter, value: str | None) -> Address | None:
        if value is None:
            return None
        if value.isascii() and value.isdigit():
            return host, _port(value, value)
        return parse_address(value, None)

    return convert


def _port(text: str, whole: str) -> int:
    # Five digits at most: int() refuses a few thousand (ValueError, not a usage error).
    if not (text.isascii() and text.isdigit() and len(text) <= 5 and 0 < int(text) < 65536):
        _fail(whole, "is not a port 1 to 65535" if text == whole else "has no port 1 to 65535")
    return int(text)


def _fail(text: str, why: str) -> NoReturn:
    raise click.BadParameter(f"{quoted(text)} {why}")
