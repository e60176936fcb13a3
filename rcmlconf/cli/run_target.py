"""The implementations under test (`run --target`, `--rsp-target`) are reached once before any
case runs. One that is not there is then one line and status 2 (the harness cannot do its job),
not every case in error, or, for a robot that never answers HELLO, failing R-RSP-20.

An RCTP server gets a TCP connection, closed at once; one it takes and resets is there too
(D-RCTP-1), and its cases say what it did. An RSP robot gets one empty datagram, which
it drops unanswered, as every packet shorter than the 20-byte header (D-RSP-10, R-RSP-18): a host
where nothing listens on the port answers it with ICMP "port unreachable", which the socket
reports; a silent host says nothing, and the cases go on to find out."""

from __future__ import annotations

import socket
import sys

from rcmlconf.cli.console import Output
from rcmlconf.cli.hosts import Address
from rcmlconf.conformance.probes.lost import by_target
from rcmlconf.rcml.model import RcmlDocument
from rcmlconf.rcml.url import RctpUrl
from rcmlconf.reference.client.fetching import Deadline
from rcmlconf.reference.client.files import NoModel, from_index

#: How long the first connection may take, before --timeout-scale (a case's own bound).
CONNECT_WAIT = 5.0
#: How long a robot's host has to say "port unreachable": it does at once, or not at all.
UNREACHABLE_WAIT = 0.5
_RUNNING = "is the target running, on that port?"


def server_problem(address: Address, wait: float) -> str | None:
    """Why no TCP connection to `address` could be made within `wait` seconds, and what to look
    at, or None."""
    try:
        with socket.create_connection(address, timeout=wait):
            return None
    except socket.gaierror as error:
        return _unknown(address, error)
    except TimeoutError:
        return f"no answer within {wait:g} s; {_RUNNING}"
    except OSError as error:
        if by_target(error):  # it took the connection, then reset it: it is there (D-RCTP-1)
            return None
        return f"{(error.strerror or str(error)).lower()}; {_RUNNING}"


def robot_problem(address: Address, wait: float = UNREACHABLE_WAIT) -> str | None:
    """Why a datagram to `address` cannot reach an RSP robot (nothing listens on the port, the
    name is unknown), or None when nothing says so."""
    try:
        family, kind, proto, _, where = socket.getaddrinfo(*address, type=socket.SOCK_DGRAM)[0]
    except socket.gaierror as error:
        return _unknown(address, error)
    with socket.socket(family, kind, proto) as probe:
        probe.settimeout(wait)
        try:
            probe.connect(where)
            probe.send(b"")
            probe.recv(1)
        except ConnectionRefusedError:
            return f"nothing listens there (the host answered port unreachable); {_RUNNING}"
        except TimeoutError:
            return None
        except OSError as error:
            return f"{(error.strerror or str(error)).lower()}; {_RUNNING}"
    return None


def reach(output: Output, option: str, address: Address, via: str, problem: str | None) -> None:
    """The implementation at `address` (given as `option`, reached `via` a protocol) can be
    reached, or the run ends now (status 2)."""
    if problem is not None:
        output.problem("run", f"cannot reach {option} {described(address)} ({via}): {problem}")
        sys.exit(2)


def described(address: Address) -> str:
    """`host:port`, an IPv6 host in brackets."""
    host, port = address
    return f"[{host}]:{port}" if ":" in host else f"{host}:{port}"


def _unknown(address: Address, error: socket.gaierror) -> str:
    return f"cannot look {address[0]} up: {error.strerror}; is the name right?"


def fetched_robot(output: Output, address: Address, wait: float) -> RcmlDocument:
    """--target's RCML when --rcml is not given: the one the server's files list (D-RCTP-29), as
    a client given only an RCTP URL looks for it, the index and the RCML within `wait` seconds
    together; or the run ends now (status 2): without the robot's nodes the cases could test
    little, and CONNECT's site path would be a guess."""
    files = RctpUrl(*address, "/").files_url
    try:
        robot = from_index(files, Deadline(wait), hint="give --rcml ROBOT.rcml")
    except NoModel as problem:
        output.problem("run", f"--target {described(address)} without --rcml: {problem}")
        sys.exit(2)
    output.notice(f"the robot's RCML: {robot.title or robot.site.path}, from its files (D-RCTP-29)")
    return robot
