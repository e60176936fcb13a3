"""One run of experiment 2 (`path_following`): its setting (delay, jitter, loss), the robot's
true track, and the path error and share of the lap read off it."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from rcmlconf.experiments.path_reference import ReferencePath
from rcmlconf.impair import Impairment
from rcmlconf.reference.drivers.room import Pose

#: The robot has covered a stretch of the path when it passed within this distance of it.
ON_PATH = 0.1
#: A lap is done this close to its end (the controller stops there, its nearest point ahead).
LAP_SLACK = 0.05


@dataclass(frozen=True, slots=True)
class Setting:
    delay: float
    loss: float
    jitter: float

    @property
    def impairment(self) -> Impairment:
        return Impairment(loss=self.loss, delay=self.delay, jitter=self.jitter)

    @property
    def label(self) -> str:
        return (
            f"delay {self.delay * 1000:g} ms ± {self.jitter * 1000:g}, loss {self.loss * 100:g} %"
        )


def setting(delay: float, loss: float) -> Setting:
    return Setting(delay, loss, delay / 5)


@dataclass
class PathRun:
    """One transport in one setting."""

    transport: str
    setting: Setting
    duration: float
    bandwidth: float | None = None
    #: The robot's true positions, one a control period.
    xs: list[float] = field(default_factory=list)
    ys: list[float] = field(default_factory=list)
    errors: list[float] = field(default_factory=list)
    #: Per control period of the robot: how old the command it applied was (s) ...
    command_ages: list[float] = field(default_factory=list)
    #: ... and per control period of the local system, how old its newest position was.
    pose_ages: list[float] = field(default_factory=list)
    #: Seconds from the start until the robot truly went round (None: it did not).
    lap_time: float | None = None
    #: How far along the path the robot truly got (metres; only while within ON_PATH of it).
    progress: float = 0.0
    path_length: float = 0.0
    downlink_bytes: int = 0
    uplink_bytes: int = 0
    notes: dict[str, Any] = field(default_factory=dict)

    @property
    def mean_error(self) -> float:
        return sum(self.errors) / len(self.errors)

    @property
    def rms_error(self) -> float:
        return math.sqrt(sum(e * e for e in self.errors) / len(self.errors))

    @property
    def max_error(self) -> float:
        return max(self.errors)

    @property
    def completion(self) -> float:
        """The share of the lap the robot covered (1: all of it)."""
        return min(self.progress / self.path_length, 1.0) if self.path_length else 0.0

    def track(self, path: ReferencePath, pose: Pose, elapsed: float) -> None:
        """One sample of the robot's true pose `elapsed` seconds into the lap: its error, and
        its progress along the path (the lap time once it has gone round)."""
        self.xs.append(pose.x)
        self.ys.append(pose.y)
        error = path.distance(pose.x, pose.y)
        self.errors.append(error)
        self.path_length = path.length
        if error <= ON_PATH and self.progress < path.length:
            found = path.nearest(pose.x, pose.y, self.progress, 0.05, 0.2)
            self.progress = max(self.progress, found)
            if self.progress >= path.length - LAP_SLACK and self.lap_time is None:
                self.lap_time = elapsed

    def summary(self) -> dict[str, Any]:
        return {
            "transport": self.transport,
            "delay": self.setting.delay,
            "jitter": self.setting.jitter,
            "loss": self.setting.loss,
            "bandwidth": self.bandwidth,
            "mean_error": self.mean_error,
            "rms_error": self.rms_error,
            "max_error": self.max_error,
            "final_error": self.errors[-1],
            "completion": self.completion,
            "lap_time": self.lap_time,
            "mean_command_age": mean_or_nan(self.command_ages),
            "max_command_age": max(self.command_ages, default=math.nan),
            "mean_pose_age": mean_or_nan(self.pose_ages),
            "max_pose_age": max(self.pose_ages, default=math.nan),
            "downlink_bytes": self.downlink_bytes,
            "uplink_bytes": self.uplink_bytes,
            **self.notes,
        }


def mean_or_nan(values: Sequence[float]) -> float:
    """The mean of `values`; NaN when there are none (a run that never heard a command)."""
    return sum(values) / len(values) if values else math.nan
