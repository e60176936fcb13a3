"""Planted robustness bugs, for the fuzzer's tests (`--bug NAME`, `--list-bugs`).

They are not conformance faults (`--fault`): each is a crash, a hang, a leak or a wrong answer
that only an input off the beaten track brings out, in one protocol state. With no `--bug`
nothing here runs, and the local system is the correct one.
"""

from __future__ import annotations

import os
import sys
import time
import traceback
from typing import NoReturn

# name -> (oracle, state the input must arrive in, "data" or "control", the trigger)
BUGS: dict[str, tuple[str, str, str, str]] = {
    "welcome-buffer-crash": (
        "crash",
        "hello sent",
        "control",
        "a WELCOME whose buffer byte is above the model's commandBuffers kills the process",
    ),
    "bad-field-crash": (
        "crash",
        "welcomed",
        "data",
        "an UPLINK payload with a string or bytes length above its size, or a bool byte"
        " other than 0 and 1, kills the process",
    ),
    "bye-reason-crash": (
        "crash",
        "welcomed",
        "control",
        "a BYE of the session with a reason above 2 kills the process",
    ),
    "old-memory-event-hang": (
        "hang",
        "memory event taken",
        "data",
        "an UPLINK carrying a memory event whose ID is old (not new by D-RSP-16) and not the"
        " last one taken of its device blocks the local system for 30 s",
    ),
    "future-ack-leak": (
        "leak",
        "welcomed",
        "control",
        "each ACK item naming a command or memory command ID the local system has not sent"
        " yet keeps 1 MiB",
    ),
    "map-padding-taken": (
        "violation",
        "welcomed",
        "data",
        "an UPLINK or ACK with a Device Map bit past the last device is taken (its memory"
        " events ACKed), not dropped as malformed",
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
    """Block the one thread, and so the local system's loop, without burning the CPU."""
    time.sleep(HANG_SECONDS)


def leak(seed: bytes) -> None:
    """Keep 1 MiB made of seed; every page is written, so the RSS grows by it."""
    if len(_leaked) < LEAK_CAP:
        _leaked.append(bytearray((seed or b"\xa5") * (MIB // max(1, len(seed)) + 1))[:MIB])


def listing() -> str:
    return "".join(f"{n}\t{o}\t{s}\t{w}\t{d}\n" for n, (o, s, d, w) in BUGS.items())
