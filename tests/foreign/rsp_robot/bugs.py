"""Planted robustness bugs, for the fuzzer's tests (`--bug NAME`, `--list-bugs`).

They are not conformance faults (`--fault`): each is a crash, a hang, a leak or a wrong answer
that only an input off the beaten track brings out, in one protocol state. With no `--bug`
nothing here runs, and the robot is the correct one.
"""

from __future__ import annotations

import os
import sys
import time
import traceback
from typing import NoReturn

# name -> (oracle, state the input must arrive in, "data" or "control", the trigger)
BUGS: dict[str, tuple[str, str, str, str]] = {
    "hello-period-crash": (
        "crash",
        "any",
        "control",
        "a HELLO asking a period below 5 ms (0 to 4) kills the process",
    ),
    "map-padding-crash": (
        "crash",
        "welcomed",
        "data",
        "a DOWNLINK or ACK of the session with a Device Map bit past the last device"
        " kills the process",
    ),
    "clear-buffer-crash": (
        "crash",
        "memory command buffered",
        "control",
        "a newer DOWNLINK with Clear Buffer set, once the session has taken a memory command,"
        " kills the process at its next packet",
    ),
    "stamp-jump-hang": (
        "hang",
        "module active",
        "control",
        "a newer DOWNLINK with a value of an effector of an active module, stamped behind that"
        " effector's last value or 2^24 ms or more ahead of it, blocks the robot for 30 s",
    ),
    "far-waypoint-leak": (
        "leak",
        "memory command buffered",
        "data",
        "each DOWNLINK carrying a memory command with an integer field of magnitude 2^30 or"
        " more, once the session has taken a memory command, keeps 1 MiB",
    ),
    "trailing-bytes-taken": (
        "violation",
        "welcomed",
        "data",
        "a DOWNLINK with bytes after its payloads is taken (states applied, commands ACKed),"
        " not dropped as malformed",
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
    """Block the one thread, and so the robot's loop, without burning the CPU."""
    time.sleep(HANG_SECONDS)


def leak(seed: bytes) -> None:
    """Keep 1 MiB made of seed; every page is written, so the RSS grows by it."""
    if len(_leaked) < LEAK_CAP:
        _leaked.append(bytearray((seed or b"\xa5") * (MIB // max(1, len(seed)) + 1))[:MIB])


def listing() -> str:
    return "".join(f"{n}\t{o}\t{s}\t{w}\t{d}\n" for n, (o, s, d, w) in BUGS.items())
