"""Planted robustness bugs, for the fuzzer's tests (`--bug NAME`, `--list-bugs`).

They are not conformance faults (`--fault`): each is a crash, a hang, a leak or a wrong answer
that only an input off the beaten track brings out, in one protocol state. With no `--bug`
nothing here runs, and the server is the correct one.
"""

from __future__ import annotations

import os
import sys
import time
import traceback
from typing import NoReturn

# name -> (oracle, state the input must arrive in, "data" or "control", the trigger)
BUGS: dict[str, tuple[str, str, str, str]] = {
    "content-length-sign": (
        "crash",
        "connected",
        "control",
        "a request whose Content-Length value starts with a sign (+ or -) kills the process",
    ),
    "zero-padded-length": (
        "crash",
        "stream ready",
        "control",
        "a message whose Content-Length has a leading zero (00, 007) kills the process"
        " once an event or stream access of the session is set up (ready or playing)",
    ),
    "bare-lf-hang": (
        "hang",
        "session open",
        "control",
        "a line ending in a bare LF, on a connection whose session is open, blocks the"
        " event loop for 30 s",
    ),
    "flow-top-bit-hang": (
        "hang",
        "playing",
        "data",
        "a FLOW set-interval (read) or set-timeout (write) whose value is 2^31 or more,"
        " for a playing stream, blocks the event loop for 30 s",
    ),
    "repeated-field-acquired": (
        "violation",
        "acquired",
        "control",
        "a request repeating Session, Content-Length, Content-Type, Nodes or Transport,"
        " from a session holding a privilege, is served as if the field came once (not 400)",
    ),
    "bad-data-leak": (
        "leak",
        "playing",
        "data",
        "each DATA payload for a playing stream that does not decode as the stream's"
        " writable values (any length off) keeps 1 MiB",
    ),
    "stop-pending-crash": (
        "crash",
        "stop unanswered",
        "control",
        "a request naming a stream access (GO, PAUSE, STOP, SETUP, ACQUIRE, RELEASE of its"
        " path) while the server's own STOP of that stream, sent for its receive timeout"
        " (R-RCTP-45), is still unanswered, kills the process",
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
    """Block the one thread, and so the event loop, without burning the CPU."""
    time.sleep(HANG_SECONDS)


def leak(seed: bytes) -> None:
    """Keep 1 MiB made of seed; every page is written, so the RSS grows by it."""
    if len(_leaked) < LEAK_CAP:
        _leaked.append(bytearray((seed or b"\xa5") * (MIB // max(1, len(seed)) + 1))[:MIB])


def listing() -> str:
    return "".join(f"{n}\t{o}\t{s}\t{w}\t{d}\n" for n, (o, s, d, w) in BUGS.items())
