"""What an RXID session's href leads to (D-RXID-3), as the loader's resolver reports it."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from rcmlconf.rcml.model import RcmlDocument


@dataclass(frozen=True, slots=True)
class Unresolved:
    """The session's RCML cannot be had without fetching (R-RXID-10): links go unchecked."""

    reason: str


@dataclass(frozen=True, slots=True)
class Broken:
    """The session's RCML is missing or invalid (R-RXID-11)."""

    reason: str


SessionTarget = RcmlDocument | Unresolved | Broken
#: From a session's href to what it names.
Resolver = Callable[[str], SessionTarget]
