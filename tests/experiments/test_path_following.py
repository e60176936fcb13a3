"""Experiment 2 (paper Fig. 11): path following over RSP and over fixed-size packets on TCP,
on short runs; and the TCP model it compares with."""

from __future__ import annotations

from functools import cache

import pytest
from support.rsp_models import robot_model

from rcmlconf.experiments import path_following as pf
from rcmlconf.experiments.path_run import PathRun, setting
from rcmlconf.experiments.tcp import TcpSettings, TcpSimulation
from rcmlconf.impair import Impairment

#: Seconds of lap after the warm-up: about a third of it.
DURATION = 8.0


@cache
def run(transport: str, delay: float, loss: float, seed: int = 0) -> PathRun:
    return pf.run_path(robot_model(), transport, setting(delay, loss), duration=DURATION, seed=seed)


def test_rsp_follows_the_path_where_fixed_size_tcp_falls_behind() -> None:
    """Delay 100 ms and loss 10 %: RSP drives on, a centimetre from the path. Fixed-size TCP
    cannot carry its 4 kB every 20 ms at that loss: after the warm-up its queue holds more
    than the run and the robot never leaves the start. (Its path error is then 0, for it
    stands on the path: the share of the lap done is what tells the two apart.)"""
    rsp, tcp = run("rsp", 0.1, 0.1), run("tcp", 0.1, 0.1)
    assert rsp.completion > 0.3
    assert rsp.mean_error < 0.015
    assert rsp.max_error < 0.03
    assert tcp.completion < 0.05
    assert min(tcp.command_ages) > 5.0  # every command it applied was seconds old
    assert run("tcp-linux", 0.1, 0.1).completion < 0.05


def test_rsp_has_the_smaller_path_error_where_tcp_moves() -> None:
    """Delay 100 ms and loss 1 %: the TCP robot moves, on ever older commands, and leaves the
    path; RSP's error is its controller's."""
    rsp, tcp = run("rsp", 0.1, 0.01), run("tcp", 0.1, 0.01)
    assert rsp.mean_error < tcp.mean_error
    assert rsp.max_error < tcp.max_error
    assert tcp.max_error > 0.1


def test_without_loss_the_transports_follow_alike() -> None:
    rsp, tcp = run("rsp", 0.05, 0.0), run("tcp", 0.05, 0.0)
    assert abs(rsp.mean_error - tcp.mean_error) < 0.005
    assert rsp.completion == pytest.approx(tcp.completion, abs=0.02)
    # The fixed size costs serialisation at 2 Mbit/s: TCP's commands are older.
    assert sum(tcp.command_ages) / len(tcp.command_ages) > sum(rsp.command_ages) / len(
        rsp.command_ages
    )


@pytest.mark.parametrize("transport", ["rsp", "tcp"])
def test_the_same_seed_gives_the_same_run(transport: str) -> None:
    again = pf.run_path(robot_model(), transport, setting(0.1, 0.1), duration=DURATION)
    first = run(transport, 0.1, 0.1)
    assert (again.xs, again.ys, again.errors) == (first.xs, first.ys, first.errors)


# -- the TCP model ------------------------------------------------------------------------------


def stream(
    loss: float, settings: TcpSettings, *, seconds: float = 20.0, size: int = 3000
) -> tuple[TcpSimulation, list[tuple[int, float]]]:
    """A message of `size` bytes every 20 ms for `seconds`, then time to deliver them all."""
    sim = TcpSimulation(
        down_size=size,
        up_size=10,
        downlink=Impairment(loss=loss, delay=0.05),
        uplink=Impairment(loss=loss, delay=0.05),
        seed=1,
        bandwidth=10_000_000,
        settings=settings,
    )
    got: list[tuple[int, float]] = []
    sim.robot_listeners.append(lambda message, now: got.append((message, now)))
    count = round(seconds / 0.02)

    def write(now: float) -> None:
        if len(written) < count:
            written.append(now)
            sim.send_down(len(written) - 1, now)

    written: list[float] = []
    sim.every(0.02, write, 0.0)
    sim.run_until(seconds + 120.0, lambda: len(got) == count)
    return sim, got


@pytest.mark.parametrize(
    "settings",
    [TcpSettings(), TcpSettings(recovery="rack", congestion=True)],
    ids=["timeout-only", "linux-like"],
)
def test_tcp_delivers_every_message_once_in_order(settings: TcpSettings) -> None:
    sim, got = stream(0.05, settings)
    assert [m for m, _ in got] == list(range(1000))
    assert sim.down.stats.retransmissions > 0


def test_tcp_without_loss_takes_the_delay_and_the_serialisation() -> None:
    _, got = stream(0.0, TcpSettings(), seconds=2.0)
    serialise = (1448 + 52 + 1448 + 52 + 104 + 52) * 8 / 10_000_000
    latencies = [now - 0.02 * m for m, now in got]
    assert min(latencies) == pytest.approx(0.05 + serialise, abs=1e-9)
    assert max(latencies) < 0.05 + 2 * serialise


def test_a_lost_segment_holds_back_everything_behind_it() -> None:
    """Head-of-line blocking: with the timeout as its only recovery, a loss delays the messages
    after it by at least the 200 ms floor of the RTO."""
    sim, got = stream(0.02, TcpSettings())
    latencies = [now - 0.02 * m for m, now in got]
    assert max(latencies) > 0.05 + 0.2
    assert sim.down.stats.timeouts > 0
    assert sim.down.srtt is not None
    assert sim.down.rto >= sim.down.srtt + 0.2 - 1e-9
