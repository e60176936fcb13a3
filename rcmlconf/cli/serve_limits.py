"""`serve`'s options for what one peer may take (D-RCTP-32): the connection and session caps and
the slow-connection timeout, with the reference's defaults."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar

import click

from rcmlconf.cli.params import seconds
from rcmlconf.reference.server.limits import DEFAULT_LIMITS, ServerLimits

F = TypeVar("F", bound=Callable[..., Any])

_COUNT = click.IntRange(1, 1_000_000)


#: Each option: its name, its type, the default's field of ServerLimits, and its help.
_OPTIONS: tuple[tuple[str, click.ParamType[Any], str, str], ...] = (
    (
        "--max-connections",
        _COUNT,
        "connections",
        "Open connections at once, RCTP's and the files' together (fewer if the process may "
        "not open that many files); one beyond closes, to make room, the oldest connection "
        "without a session of the address holding the most, or is closed at once when every "
        "connection holds a session.",
    ),
    (
        "--max-connections-per-peer",
        _COUNT,
        "connections_per_peer",
        "Open connections of one address at once (R-RCTP-67: at least 64).",
    ),
    (
        "--max-sessions-per-peer",
        _COUNT,
        "sessions_per_peer",
        "Sessions of one address at once; a CONNECT beyond is answered 503 (R-RCTP-67: at "
        "least 32).",
    ),
    (
        "--slow-timeout",
        seconds(3600.0),
        "slow_timeout",
        "Close a connection with no CONNECT S seconds after it opened, or with a request not "
        "whole S seconds after its first byte (R-RCTP-67: at least 10).",
    ),
)


def limit_options(command: F) -> F:
    """The four options, in _OPTIONS' order in --help."""
    for name, kind, default, text in reversed(_OPTIONS):
        metavar = "S" if name == "--slow-timeout" else "N"
        option = click.option(
            name,
            type=kind,
            default=getattr(DEFAULT_LIMITS, default),
            show_default=True,
            metavar=metavar,
            help=text,
        )
        command = option(command)
    return command


def limits_from(
    max_connections: int,
    max_connections_per_peer: int,
    max_sessions_per_peer: int,
    slow_timeout: float,
) -> ServerLimits:
    return ServerLimits(
        connections=max_connections,
        connections_per_peer=max_connections_per_peer,
        sessions_per_peer=max_sessions_per_peer,
        slow_timeout=slow_timeout,
    )
