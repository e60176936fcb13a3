"""What a probe's failed connection to the target means, in one place. A connection the target
took and then reset (D-RCTP-1), at connect or later, ended by the target's doing: the case judges
it as a connection closed, with the words `RESET`. Any other failure is not the target's: refused
(nothing listens), no route, no name, no handshake in time. That is the network's, an error.

`Contact` keeps what a case's connections found: whether the target sent a byte on any, and how
each ended. The runner gives up on a dead target from it (`conformance.giveup`)."""

from __future__ import annotations

import os
from collections import Counter
from dataclasses import dataclass, field
from typing import Protocol

from rcmlconf.conformance.transcript import Address
from rcmlconf.conformance.verdicts import CaseStop, Failed, HarnessError

#: What a case that waited for an answer got from a connection the target reset.
RESET = "the connection was reset with no answer"


def by_target(error: BaseException) -> bool:
    """Whether `error` says the target took the connection and then reset it. That is
    ECONNRESET or ECONNABORTED, at connect too (the handshake was done before the RST came),
    or EPIPE on a write after it."""
    return isinstance(error, (ConnectionResetError, ConnectionAbortedError, BrokenPipeError))


def unreached(address: Address, error: OSError) -> HarnessError:
    """The error of a connection to `address` that was never made (a reset is not one: it
    was made, `by_target`)."""
    host, port = address
    return HarnessError(f"cannot connect to {host}:{port}: {said(error)}")


def network(error: OSError, on: str = "") -> HarnessError:
    """The error of a connection made (`on`, its name) that then failed without the target's
    doing, or of a socket a case used."""
    return HarnessError(f"network error{f' on {on}' if on else ''}: {said(error)}")


def stop(error: OSError, requirement: str) -> CaseStop:
    """The verdict of an OSError no probe caught (the runner's): a reset fails `requirement`,
    the case's first; anything else is the network's error."""
    if by_target(error):
        return Failed(requirement, "the exchange carried to its end", "the target reset it")
    return network(error)


def said(error: OSError) -> str:
    """`connection refused`: the system's words for the error, not asyncio's ("Connect call
    failed ('127.0.0.1', 7400)"); a resolver's own (its codes are below 0); `timed out`."""
    if error.errno is not None and error.errno > 0:
        return os.strerror(error.errno).lower()
    if isinstance(error, TimeoutError):
        return "timed out"
    return str(error.strerror or error) or type(error).__name__


def named(name: object, known: Address) -> Address:
    """(host, port) of a socket's name as asyncio read it (IPv6's has two fields more), else
    `known`: what the probe knew (the address it connected to). The socket of a connection
    reset as it was made has no peer."""
    if isinstance(name, tuple) and len(name) >= 2:
        return str(name[0]), int(name[1])
    return known


class Connection(Protocol):
    """A connection as `Contact` reads it (`ControlProbe`)."""

    @property
    def heard(self) -> int:
        """Bytes the target sent on it."""
        ...

    @property
    def end(self) -> str:
        """How it ended: open (not yet), closed or reset."""
        ...


@dataclass(eq=False)
class Contact:
    """One case's connections to the target: those made and why the rest were not."""

    made: list[Connection] = field(default_factory=list)
    #: For each connection never made: "refused", or "unreached" (no handshake, no route).
    unmade: list[str] = field(default_factory=list)

    def failed(self, error: OSError) -> None:
        self.unmade.append("refused" if isinstance(error, ConnectionRefusedError) else "unreached")

    @property
    def heard(self) -> bool:
        """Whether the target sent a byte on any of them."""
        return any(connection.heard for connection in self.made)

    def datagrams(self, sent: bool, heard: bool) -> None:
        """The case's datagrams to an RSP robot, which has no connections: as one that ended
        "unanswered" when the case sent the robot some and heard none back."""
        if sent:
            self.made.append(_Datagrams(int(heard), "open" if heard else "unanswered"))

    def ends(self) -> Counter[str]:
        """How each connection tried ended, the target having sent nothing on it: "reset",
        "closed", "silent" (still open), "refused", "unreached", "unanswered" (datagrams)."""
        found = Counter("silent" if c.end == "open" else c.end for c in self.made if not c.heard)
        found.update(self.unmade)
        return found


@dataclass(frozen=True, slots=True)
class _Datagrams:
    """A case's datagrams to an RSP robot, as a `Connection`."""

    heard: int
    end: str
