"""What the implementation under test is: the four roles of the two protocols' ends."""

from __future__ import annotations

import enum


class Role(enum.Enum):
    """What the implementation under test is."""

    #: An RCTP/2.0 server (`--target`).
    SERVER = "server"
    #: An RCTP/2.0 client; the harness plays the server (`--role client --listen`).
    CLIENT = "client"
    #: An RSP robot; the harness plays the local system (`--rsp-target`).
    ROBOT = "robot"
    #: An RSP local system; the harness plays the robot (`--role local --listen`).
    LOCAL = "local"
