"""The batch adapter (`reference.rsp.batch`): many robots and simulacrums on one reader and one
clock, over real UDP sockets on 127.0.0.1."""

from __future__ import annotations

import asyncio
import socket

from support.rsp_models import EVERY_KIND, robot_model
from support.servers import run

from rcmlconf.reference.rsp.batch import READS_A_WAKEUP, Batch
from rcmlconf.reference.rsp.robot import ReferenceRobot, RobotSettings
from rcmlconf.reference.rsp.simulacrum import Simulacrum
from rcmlconf.rsp.session import events

ARM = {"shoulder": 10, "elbow": 20, "grip": True}
PAIRS = 8


async def settled(local: Simulacrum, device: str, values: object) -> None:
    """Until `device`'s newest value is `values` (the test's bound stops a wait for ever)."""
    while local.latest(device) != values:
        await asyncio.sleep(0.01)


@run
async def test_many_pairs_share_one_batch() -> None:
    loop = asyncio.get_running_loop()
    batch = Batch(loop)
    model = robot_model(EVERY_KIND)
    robots = [ReferenceRobot(model, RobotSettings(port=0)) for _ in range(PAIRS)]
    for robot in robots:
        await robot.start(batch)
    locals_ = [Simulacrum(model, robot.address) for robot in robots]
    for local in locals_:
        opened = await local.open(timeout=5, batch=batch)
        assert opened.period == model.period
    for number, local in enumerate(locals_):
        local.write("arm", {**ARM, "shoulder": number})
        local.set_active("armActual", True)
    for number, local in enumerate(locals_):
        # Each robot answers its own local system only (D-RSP-12): its own arm comes back.
        await settled(local, "armActual", {**ARM, "shoulder": number})
    sent = [local.endpoint.packets_sent for local in locals_]
    await asyncio.sleep(10 * model.period)
    for before, local in zip(sent, locals_, strict=True):
        assert local.endpoint.packets_sent >= before + 5  # the beat goes on, on the batch's clock
    for local in locals_:
        await local.aclose()
    await asyncio.sleep(0.05)
    for robot in robots:
        assert robot.endpoint.session is None  # BYE reached it
        assert any(isinstance(event, events.SessionClosed) for event in robot.history)
        robot.stop()
    batch.close()


@run
async def test_a_robot_on_a_batch_serves_a_simulacrum_on_asyncio() -> None:
    """The adapters speak the same RSP: a batch's robot, an asyncio transport's local system."""
    batch = Batch(asyncio.get_running_loop())
    robot = ReferenceRobot(robot_model(EVERY_KIND), RobotSettings(port=0))
    await robot.start(batch)
    local = Simulacrum(robot.model, robot.address)
    await local.open(timeout=5)
    local.write("arm", ARM)
    local.set_active("armActual", True)
    await settled(local, "armActual", ARM)
    await local.aclose()
    robot.stop()
    batch.close()
    assert robot.transport is not None
    assert robot.transport.is_closing()


@run
async def test_a_beat_due_waits_for_one_wake_ups_reads_not_for_all() -> None:
    """More sockets with a datagram than one wake-up reads: the timer due runs after the first
    READS_A_WAKEUP of them, and the rest are read at the wake-ups after it, none lost."""
    loop = asyncio.get_running_loop()
    batch = Batch(loop)
    sockets = 3 * READS_A_WAKEUP + 5
    received: list[bytes] = []
    ports = [batch.open(lambda data, addr: received.append(data)) for _ in range(sockets)]
    seen_by_beat: list[int] = []
    batch.timer(lambda: seen_by_beat.append(len(received))).set(loop.time() - 0.01)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sender:
        for number, port in enumerate(ports):
            sender.sendto(number.to_bytes(2, "big"), port.get_extra_info("sockname"))
        while len(received) < sockets:
            await asyncio.sleep(0.001)
    assert seen_by_beat == [READS_A_WAKEUP]
    assert sorted(received) == [number.to_bytes(2, "big") for number in range(sockets)]
    batch.close()
