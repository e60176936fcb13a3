"""RCML models the tests run robots, servers and streams on, each loaded once."""

from __future__ import annotations

from functools import cache
from pathlib import Path

from rcmlconf.rcml.model import AccessNode, RcmlDocument
from rcmlconf.validate.validator import load_robot

ROOT = Path(__file__).resolve().parents[2]
TESTBOT = ROOT / "vectors" / "xml" / "valid" / "testbot.rcml"
ROBOTS = ROOT / "rcmlconf" / "reference" / "robots"
CAMERA = ROBOTS / "camera" / "camera.rcml"
ROVER = ROBOTS / "rover" / "rover.rcml"
#: The robot the conformance harness plays to a client under test (D-RCTP-31).
HARNESS = ROOT / "rcmlconf" / "conformance" / "robot" / "harness.rcml"


@cache
def robot(path: Path = TESTBOT) -> RcmlDocument:
    return load_robot(path)


def access(path: str, model: Path = TESTBOT) -> AccessNode:
    node = robot(model).node(path)
    assert isinstance(node, AccessNode), path
    return node
