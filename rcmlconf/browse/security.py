"""Who may use the panel: nobody but the user who started it drives the robot.

As Jupyter does, the command prints a URL with a random token, and every request, the page's
and its WebSocket's, must carry it. Two more checks stop what the token alone does not:
- `Host` (DNS rebinding): a page of evil.example whose name is made to resolve to 127.0.0.1 sends
  `Host: evil.example`. Only an IP literal or `localhost`, with the panel's port, is taken.
- `Origin` (another page in the same browser): a page of another origin that learned the URL
  could open the WebSocket from the user's browser. A request that has an Origin must come from
  the panel's own (`http://` + its Host); the WebSocket must have one, since browsers always send
  it there.
"""

from __future__ import annotations

import hmac
import ipaddress
import secrets
from collections.abc import Callable
from urllib.parse import parse_qs, urlsplit

#: The bytes of randomness in a token (Jupyter's has 24 too).
TOKEN_BYTES = 24


def new_token() -> str:
    return secrets.token_urlsafe(TOKEN_BYTES)


def is_loopback(host: str) -> bool:
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


class Guard:
    def __init__(self, token: str, port: int) -> None:
        self.token = token
        self.port = port

    def refusal(self, target: str, header: Callable[[str], str | None], socket: bool) -> str | None:
        """Why a request for `target` (path and query) with these headers is refused, or None.
        `socket`: the request opens the WebSocket."""
        host = header("Host")
        if host is None or not self._our_host(host):
            return f"Host {host!r} is not this panel's (127.0.0.1 or localhost, port {self.port})"
        origin = header("Origin")
        if origin is None and socket:
            return "a WebSocket without an Origin"
        if origin is not None and origin != f"http://{host}":
            return f"Origin {origin!r} is not this panel's (http://{host})"
        try:
            given = parse_qs(urlsplit(target).query).get("token", [""])[0]
        except ValueError:
            given = ""
        if not hmac.compare_digest(given.encode(), self.token.encode()):
            return "no token, or not this panel's: use the URL the command printed"
        return None

    def _our_host(self, host: str) -> bool:
        name, colon, port = host.rpartition(":")
        if not colon or port != str(self.port):
            return False
        if name == "localhost":
            return True
        try:
            ipaddress.ip_address(name[1:-1] if name.startswith("[") else name)
        except ValueError:
            return False
        return True
