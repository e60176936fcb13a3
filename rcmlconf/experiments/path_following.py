"""Experiment 2 of the RSP paper (§IV.B, Fig. 11): path following under delay and loss.

"The local system controlled the remote robot in order to follow the path based on the
transmitted position data. [...] the path error of RSP was smaller than a result by the fixed
packet size. [...] RSP is more robust than TCP using the fixed packet size in the transmission
delay." T was 20 ms; the robot returned its global position.

Here the local system drives a simulated CUBO (`CuboBody`) around a reference path, a 2 m x 1 m
rectangle with corners rounded to 0.3 m (5.49 m a lap), with a pure-pursuit controller fed only
by the position values it receives. Every T (20 ms) the controller takes the newest position,
finds the path point `LOOKAHEAD` ahead of the nearest one, and sets the wheel speeds of the arc
through it at `SPEED`; after one lap (by its own reckoning) it stops the wheels. The robot
reports its position every T. Both directions suffer the same delay, jitter and loss (an
`impair.Impairment` each way) and share a bottleneck of `bandwidth` bits/s each way.

Transports:

- `rsp`: RSP over UDP (`RspSimulation`): a DOWNLINK with the two wheel speeds, the `base` module
  bit and the position request every T, an UPLINK with the position every T; the robot's motion
  filter holds, collapses, interpolates and stops on a lost link (D-RSP-20).
- `tcp`: fixed-size packets over TCP (`tcp.TcpSimulation`), the plainest TCP the paper could
  have meant: every DOWNLINK is the model's largest (4,060 bytes), every UPLINK too (1,045
  bytes), the timeout is its only loss recovery and it has no congestion window (the
  bottleneck's queue takes what it sends). The robot applies the newest command it has each
  control period (as a robot reading its socket dry would) and holds it when none comes.
- `tcp-linux`: the same packets over a TCP as Linux runs it: SACK and RACK loss detection,
  and a congestion window (CUBIC's β = 0.7).
- `tcp-small`: not the paper's baseline, but what separates the two causes: RSP's own packet
  sizes (the DOWNLINK of the two wheels, the UPLINK of the position) over the Linux-like TCP.

Both transports first send `WARMUP` seconds of zero commands (TCP's slow start is then over);
the lap starts after. The path error is the distance of the robot's true pose (not the reported
one) from the reference path, sampled every control period of the lap's run: mean, RMS and max.
Beside it, the share of the lap the robot truly covered: a robot that never leaves the start
stands on the path, and its path error is 0.

Here: the settings, a lap over each transport (`run_path`) and the sweep (`run_sweep`). The path
is `path_reference`, the controller `path_controller`, a run's record and path error `path_run`,
the report `path_report`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from rcmlconf.experiments.path_controller import LOOKAHEAD, SPEED, PurePursuit
from rcmlconf.experiments.path_reference import HEIGHT, RADIUS, WIDTH, ReferencePath
from rcmlconf.experiments.path_run import PathRun, Setting, mean_or_nan, setting
from rcmlconf.experiments.simulation import EPSILON, RspSimulation
from rcmlconf.experiments.tcp import TcpSettings, TcpSimulation
from rcmlconf.reference.drivers.room import Pose
from rcmlconf.reference.rsp.cubo import CuboBody
from rcmlconf.rsp.codec import Encryption
from rcmlconf.rsp.layout import HEADER_SIZE, TAG_SIZE, MapPacket, largest_packet
from rcmlconf.rsp.model import RobotModel
from rcmlconf.rsp.session import events

PERIOD = 0.02
#: A lap at SPEED and a little more: the run's default length.
DEFAULT_DURATION = 25.0
#: Seconds of zero commands before the lap, so that a TCP connection's slow start is over
#: (and its window fitted to the stream) when the robot starts: both transports get them.
WARMUP = 10.0
#: The bottleneck each way, bits/s (see `path_report`).
DEFAULT_BANDWIDTH = 2_000_000
#: Settings of the sweep: one-way delay (s) and loss; jitter is a fifth of the delay.
DELAYS = (0.05, 0.1, 0.2)
LOSSES = (0.0, 0.01, 0.05, 0.1, 0.2)
TRANSPORTS = ("rsp", "tcp", "tcp-linux", "tcp-small")
#: The settings of the figure: (delay, loss).
FIGURE_SETTINGS = ((0.1, 0.01), (0.1, 0.1))
#: Each TCP transport: its TCP, and whether its packets are the model's largest (fixed) or the
#: size RSP's would be.
TCP_TRANSPORTS = {
    "tcp": (TcpSettings(recovery="rto", congestion=False), True),
    "tcp-linux": (TcpSettings(recovery="rack", congestion=True), True),
    "tcp-small": (TcpSettings(recovery="rack", congestion=True), False),
}


def fixed_sizes(model: RobotModel) -> tuple[int, int]:
    """The model's largest DOWNLINK and UPLINK without encryption: TCP's fixed packets."""
    return (
        largest_packet(model, MapPacket.DOWNLINK) - TAG_SIZE,
        largest_packet(model, MapPacket.UPLINK) - TAG_SIZE,
    )


def rsp_sizes(model: RobotModel) -> tuple[int, int]:
    """RSP's packets in this experiment: the DOWNLINK of the two wheel speeds (module and
    request bits bring no payload) and the UPLINK of the position."""

    def payload(*names: str) -> int:
        return sum(f.type.max_encoded_size for n in names for f in model.by_name[n].fields)

    base = HEADER_SIZE + model.map_size
    return base + payload("leftWheel", "rightWheel"), base + payload("position")


def run_path(
    model: RobotModel,
    transport: str,
    where: Setting,
    *,
    duration: float = DEFAULT_DURATION,
    seed: int = 0,
    bandwidth: float | None = DEFAULT_BANDWIDTH,
    path: ReferencePath | None = None,
) -> PathRun:
    """Drive one lap (or `duration` seconds) with one transport in one setting."""
    path = path or ReferencePath()
    if transport == "rsp":
        return _run_rsp(model, where, duration, seed, bandwidth, path)
    if transport in TCP_TRANSPORTS:
        return _run_tcp(model, transport, where, duration, seed, bandwidth, path)
    raise ValueError(f"transport is one of {TRANSPORTS}, not {transport!r}")


def _mm(speed: float) -> int:
    return max(-500, min(500, round(speed * 1000)))


def _run_rsp(
    model: RobotModel,
    where: Setting,
    duration: float,
    seed: int,
    bandwidth: float | None,
    path: ReferencePath,
) -> PathRun:
    body = CuboBody(model, path.start, seed=seed)
    impairment = where.impairment
    sim = RspSimulation(
        model,
        downlink=impairment,
        uplink=impairment,
        seed=seed,
        period=PERIOD,
        encryption=Encryption.NONE,
        bandwidth=bandwidth,
        body=body,
    )
    run = PathRun("rsp", where, duration, bandwidth)
    controller = PurePursuit(path)
    newest: list[tuple[Pose, float]] = []  # the newest position and when it was measured
    command_time: list[float] = []
    lost = [0]

    def local_heard(event: events.Event, now: float) -> None:
        if isinstance(event, events.StateReceived) and event.device == "position":
            values = event.values
            x, y, heading = values["x"], values["y"], values["heading"]
            assert isinstance(x, float)
            assert isinstance(y, float)
            assert isinstance(heading, float)
            measured = robot_epoch[0] + event.stamp / 1000
            newest[:] = [(Pose(x, y, heading), measured)]
        elif isinstance(event, events.LinkLost):
            lost[0] += 1

    def robot_heard(event: events.Event, now: float) -> None:
        if isinstance(event, events.StateReceived) and event.device == "leftWheel":
            assert sim.local_epoch is not None
            command_time[:] = [sim.local_epoch + event.stamp / 1000]

    robot_epoch = [0.0]
    sim.local_listeners.append(local_heard)
    sim.robot_listeners.append(robot_heard)
    opened = sim.open()
    robot_epoch[0] = sim.sent_up.times[0]  # the WELCOME: the robot's timestamps count from it
    local = sim.local
    local.write("leftWheel", {"speed": 0})
    local.write("rightWheel", {"speed": 0})
    local.set_active("base", True)
    local.set_active("position", True)
    start = opened + PERIOD + WARMUP

    def control(now: float) -> None:
        if now < start - EPSILON:
            return  # zero speeds, written above
        pose = newest[0][0] if newest else None
        if newest:
            run.pose_ages.append(now - newest[0][1])
        left, right = controller.command(pose)
        local.write("leftWheel", {"speed": _mm(left)})
        local.write("rightWheel", {"speed": _mm(right)})

    def sample(now: float) -> None:
        run.track(path, body.pose, now - start)
        if command_time:
            run.command_ages.append(now - command_time[0])

    sim.every(PERIOD, control, opened + PERIOD)
    sim.every(PERIOD, sample, math.ceil(start / PERIOD) * PERIOD)
    sim.run_until(start + duration)
    run.downlink_bytes = sim.down.bytes
    run.uplink_bytes = sim.up.bytes
    run.notes = {
        "link_lost": lost[0],
        "downlink_lost": sim.down.counts.lost,
        "uplink_lost": sim.up.counts.lost,
    }
    return run


@dataclass(frozen=True, slots=True)
class _Command:
    left: int
    right: int
    written: float


@dataclass(frozen=True, slots=True)
class _Report:
    pose: Pose
    measured: float


def _run_tcp(
    model: RobotModel,
    transport: str,
    where: Setting,
    duration: float,
    seed: int,
    bandwidth: float | None,
    path: ReferencePath,
) -> PathRun:
    settings, fixed = TCP_TRANSPORTS[transport]
    down_size, up_size = fixed_sizes(model) if fixed else rsp_sizes(model)
    impairment = where.impairment
    sim = TcpSimulation(
        down_size=down_size,
        up_size=up_size,
        downlink=impairment,
        uplink=impairment,
        seed=seed,
        bandwidth=bandwidth,
        settings=settings,
    )
    body = CuboBody(model, path.start, seed=seed)
    run = PathRun(transport, where, duration, bandwidth)
    controller = PurePursuit(path)
    newest: list[_Report] = []
    commands: list[_Command] = []
    latencies: list[float] = []

    def robot_heard(message: Any, now: float) -> None:
        assert isinstance(message, _Command)
        latencies.append(now - message.written)
        commands[:] = [message]  # the newest: read the socket dry

    def local_heard(message: Any, now: float) -> None:
        assert isinstance(message, _Report)
        newest[:] = [message]

    sim.robot_listeners.append(robot_heard)
    sim.local_listeners.append(local_heard)
    # The connection is open at 0 (its handshake is not modelled); the first command at T.
    start = PERIOD + WARMUP

    def robot_control(now: float) -> None:
        if commands:
            command = commands[0]
            body.apply(
                {"leftWheel": {"speed": command.left}, "rightWheel": {"speed": command.right}},
                now,
            )
        body.advance(now)
        pose = body.pose
        sim.send_up(_Report(pose, now), now)
        if now >= start - EPSILON:
            run.track(path, pose, now - start)
            if commands:
                run.command_ages.append(now - commands[0].written)

    def control(now: float) -> None:
        if now < start - EPSILON:
            sim.send_down(_Command(0, 0, now), now)
            return
        report = newest[0] if newest else None
        if report is not None:
            run.pose_ages.append(now - report.measured)
        left, right = controller.command(report.pose if report else None)
        sim.send_down(_Command(_mm(left), _mm(right), now), now)

    sim.every(PERIOD, robot_control, 0.0)
    sim.every(PERIOD, control, PERIOD)
    sim.run_until(start + duration)
    run.downlink_bytes = sim.down_path.bytes
    run.uplink_bytes = sim.up_path.bytes
    down = sim.down.stats
    run.notes = {
        "segments_sent": down.segments_sent,
        "retransmissions": down.retransmissions,
        "timeouts": down.timeouts,
        "mean_delivery_latency": mean_or_nan(latencies),
        "max_delivery_latency": max(latencies, default=math.nan),
        "messages_undelivered": down.messages_written - len(latencies),
        "downlink_lost": sim.down_path.counts.lost,
        "uplink_lost": sim.up_path.counts.lost,
    }
    return run


# -- the sweep ---------------------------------------------------------------------------------


@dataclass
class PathExperiment:
    runs: list[PathRun]
    duration: float
    bandwidth: float | None
    seed: int
    #: Runs beside the sweep (another bandwidth).
    extra: list[PathRun] = field(default_factory=list)

    def find(self, transport: str, delay: float, loss: float) -> PathRun | None:
        for run in self.runs:
            s = run.setting
            if run.transport == transport and s.delay == delay and s.loss == loss:
                return run
        return None

    def summary(self) -> dict[str, Any]:
        return {
            "duration": self.duration,
            "bandwidth": self.bandwidth,
            "seed": self.seed,
            "period": PERIOD,
            "path": {"width": WIDTH, "height": HEIGHT, "radius": RADIUS},
            "controller": {"speed": SPEED, "lookahead": LOOKAHEAD},
            "runs": [run.summary() for run in self.runs],
            "extra": [run.summary() for run in self.extra],
        }


def run_sweep(
    model: RobotModel,
    *,
    delays: Sequence[float] = DELAYS,
    losses: Sequence[float] = LOSSES,
    transports: Sequence[str] = TRANSPORTS,
    duration: float = DEFAULT_DURATION,
    seed: int = 0,
    bandwidth: float | None = DEFAULT_BANDWIDTH,
) -> PathExperiment:
    path = ReferencePath()
    runs = [
        run_path(
            model,
            transport,
            setting(delay, loss),
            duration=duration,
            seed=seed,
            bandwidth=bandwidth,
            path=path,
        )
        for delay in delays
        for loss in losses
        for transport in transports
    ]
    return PathExperiment(runs, duration, bandwidth, seed)


#: Runs beside the sweep: (delay, loss, bandwidth, transports).
EXTRA_RUNS = (
    (0.05, 0.0, 1_000_000, ("rsp", "tcp")),
    (0.1, 0.01, 10_000_000, ("rsp", "tcp", "tcp-linux")),
)


def run_extra(model: RobotModel, *, duration: float, seed: int) -> list[PathRun]:
    """The sweep's transports at other bandwidths (`EXTRA_RUNS`)."""
    path = ReferencePath()
    return [
        run_path(
            model,
            transport,
            setting(delay, loss),
            duration=duration,
            seed=seed,
            bandwidth=bandwidth,
            path=path,
        )
        for delay, loss, bandwidth, transports in EXTRA_RUNS
        for transport in transports
    ]
