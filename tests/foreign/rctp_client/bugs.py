"""Planted robustness bugs, for the fuzzer's tests (`--bug NAME`, `--list-bugs`).

They are not conformance faults (`--fault`): each is a crash, a hang, a leak or a wrong answer
that only an input off the beaten track brings out, in one protocol state. With no `--bug`
nothing here runs, and the client is the correct one.
"""

from __future__ import annotations

import os
import sys
import time
import traceback
from typing import NoReturn

# name -> (oracle, state the input must arrive in, "data" or "control", the trigger)
BUGS: dict[str, tuple[str, str, str, str]] = {
    "session-timeout-crash": (
        "crash",
        "connected",
        "control",
        "a CONNECT answered 200 whose Session gives a timeout of 0 or 1 kills the process",
    ),
    "bad-push-crash": (
        "crash",
        "event playing",
        "control",
        "a data-change WRITE of a playing event access whose body does not decode as its"
        " Nodes' values (a length off, a bad byte, a value out of range) kills the process",
    ),
    "heartbeat-ack-crash": (
        "crash",
        "stream playing",
        "data",
        "a heartbeat ACK answering the client's own heartbeat whose T3 is before its T2"
        " kills the process",
    ),
    "flow-top-bit-hang": (
        "hang",
        "stream playing",
        "data",
        "a FLOW set-interval (write) or set-timeout (read) whose value is 2^31 or more,"
        " for a playing stream, blocks the client for 30 s",
    ),
    "late-packet-leak": (
        "leak",
        "stream playing",
        "data",
        "each data packet that is not newer (a repeated or older sequence number) holding"
        " DATA of a playing stream keeps 1 MiB",
    ),
    "stray-stop-200": (
        "violation",
        "playing",
        "control",
        "while an access plays, a server STOP naming no access that is set up is answered"
        " 200, not 455 (R-RCTP-68)",
    ),
}

HANG_SECONDS = 30.0
MIB = 1 << 20
LEAK_CAP = 512  # MiB: the leak stops growing there, to spare the machine
active: set[str] = set()
_leaked: list[bytearray] = []


def on(name: str) -> bool:
    return name in active


def crash(exc: BaseException) -> NoReturn:
    """Die as an uncaught exception would: its traceback on stderr, exit status 1."""
    if exc.__traceback__ is None:  # made here, not raised: show where it was hit
        print("Traceback (most recent call last):", file=sys.stderr)
        print("".join(traceback.format_stack()[:-1]), end="", file=sys.stderr)
        print("".join(traceback.format_exception_only(exc)), end="", file=sys.stderr)
    else:
        traceback.print_exception(exc, file=sys.stderr)
    sys.stderr.flush()
    os._exit(1)


def hang() -> None:
    """Block the one thread, and so the client's event loop, without burning the CPU."""
    time.sleep(HANG_SECONDS)


def leak(seed: bytes) -> None:
    """Keep 1 MiB made of seed; every page is written, so the RSS grows by it."""
    if len(_leaked) < LEAK_CAP:
        _leaked.append(bytearray((seed or b"\xa5") * (MIB // max(1, len(seed)) + 1))[:MIB])


def listing() -> str:
    return "".join(f"{n}\t{o}\t{s}\t{w}\t{d}\n" for n, (o, s, d, w) in BUGS.items())
