"""The RCTP URL `rctp://host[:port][/path]` (D-RCML-17): how an RCML document names its robot's
server, here below RCTP because RCML is (the core, the reference and the harness read it too)."""

from __future__ import annotations

import ipaddress
import re
from dataclasses import dataclass

from rcmlconf.errors import ValueTextError

#: D-RCTP-2: where a server listens unless its URL says otherwise (TCP, and UDP for the data).
DEFAULT_PORT = 7330
#: D-RCTP-29: a server's files are on HTTP at the port after its RCTP port.
FILES_PORT_OFFSET = 1

# An IPv6 literal may carry a zone as RFC 6874 writes it in URIs: "%25" and unreserved characters.
_URL = re.compile(
    r"(?i:rctp)://(?P<host>\[[0-9A-Fa-f:.]+(?:%25[A-Za-z0-9._~-]+)?\]|[A-Za-z0-9._~%-]+)"
    r"(?::(?P<port>[0-9]*))?(?P<path>/[^\s?#]*)?"
)


@dataclass(frozen=True, slots=True)
class RctpUrl:
    host: str
    #: None: the default port of RCTP.
    port: int | None
    path: str

    @property
    def port_or_default(self) -> int:
        return DEFAULT_PORT if self.port is None else self.port

    @property
    def files_url(self) -> str:
        """Where the robot's files are listed over HTTP (D-RCTP-29)."""
        return http_base(self.host, self.port_or_default + FILES_PORT_OFFSET) + "/"

    def __str__(self) -> str:
        host = f"[{self.host.replace('%', '%25')}]" if ":" in self.host else self.host
        port = "" if self.port is None else f":{self.port}"
        return f"rctp://{host}{port}{self.path}"


def parse_rctp_url(text: str) -> RctpUrl:
    match = _URL.fullmatch(text)
    if match is None:
        raise ValueTextError(
            f"{text!r} is not an RCTP URL of the form rctp://host[:port][/path] "
            "(no user, query or fragment)"
        )
    host = match.group("host")
    if host.startswith("["):
        address, _, zone = host[1:-1].partition("%25")
        try:
            host = str(ipaddress.IPv6Address(address)) + (f"%{zone}" if zone else "")
        except ValueError:
            raise ValueTextError(f"{host} is not an IPv6 address") from None
    port_text = match.group("port")
    port = None
    if port_text is not None:
        if not port_text or len(port_text) > 5 or not 1 <= int(port_text) <= 65535:
            raise ValueTextError(f"port {port_text!r} is not between 1 and 65535")
        port = int(port_text)
    return RctpUrl(host, port, match.group("path") or "/")


def http_base(host: str, port: int) -> str:
    """`http://host:port`, an IPv6 host in brackets."""
    return f"http://{f'[{host}]' if ':' in host else host}:{port}"
