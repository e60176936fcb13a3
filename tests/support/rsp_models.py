"""RSP robot models the tests run codecs, sessions and robots on, each loaded once."""

from __future__ import annotations

from functools import cache
from pathlib import Path

from rcmlconf.rsp.model import RobotModel
from rcmlconf.validate.validator import load_robot_model

ROOT = Path(__file__).resolve().parents[2]
CUBO = ROOT / "rcmlconf" / "reference" / "robots" / "cubo" / "cubo.rmodel"
EVERY_KIND = ROOT / "vectors" / "xml" / "valid" / "rmodel-every-kind.rmodel"


@cache
def robot_model(path: Path = CUBO) -> RobotModel:
    return load_robot_model(path)
