"""An RCTP server under test (`run --target`) is reached once before any case runs: a TCP
connection, closed at once. A server that is not there is then one line and status 2 (the
harness cannot do its job), not a hundred cases in error that each say the same."""

from __future__ import annotations

import socket
import sys

from rcmlconf.cli.console import Output
from rcmlconf.cli.hosts import Address

#: How long the first connection may take, before --timeout-scale (a case's own bound).
CONNECT_WAIT = 5.0


def unreachable(address: Address, wait: float) -> str | None:
    """Why no TCP connection to `address` could be made within `wait` seconds, and what to look
    at, or None."""
    host, port = address
    try:
        with socket.create_connection((host, port), timeout=wait):
            return None
    except socket.gaierror as error:
        return f"cannot look {host} up: {error.strerror}; is the name right?"
    except TimeoutError:
        why = f"no answer within {wait:g} s"
    except OSError as error:
        why = (error.strerror or str(error)).lower()
    return f"{why}; is the target running, on that port?"


def described(address: Address) -> str:
    """`host:port`, an IPv6 host in brackets."""
    host, port = address
    return f"[{host}]:{port}" if ":" in host else f"{host}:{port}"


def reach(output: Output, target: Address, wait: float) -> None:
    """The server under test answers on its port, or the run ends now (status 2)."""
    why = unreachable(target, wait)
    if why is not None:
        output.problem(
            "run",
            f"cannot connect to --target {described(target)} (RCTP over TCP): {why}",
        )
        sys.exit(2)
