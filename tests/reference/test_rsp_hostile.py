"""The reference RSP robot under a flood of hostile datagrams on 127.0.0.1, a real session going
on: garbage, packets of the session from another address (its session ID spoofed), and replays
of the session's own packets, from another address and from the local system's own. Nothing of
it is accepted, and the real session loses nothing (issue 18)."""

from __future__ import annotations

import asyncio
import dataclasses
import logging
import multiprocessing
import socket

import pytest
from support.rsp_flood import flood
from support.rsp_models import EVERY_KIND, robot_model
from support.waits import until

from rcmlconf.reference.rsp.robot import ReferenceRobot, RobotSettings
from rcmlconf.reference.rsp.simulacrum import Simulacrum
from rcmlconf.rsp.codec.header import TYPE_AT, PacketType
from rcmlconf.rsp.session import events

OLD = {"shoulder": 10, "elbow": 20, "grip": True}
NEW = {"shoulder": -30, "elbow": 45, "grip": False}
#: The model's period for this test (its own is 5 ms): the local system takes the link for lost
#: after 25 silent periods (D-RSP-13), and a loaded CI machine can hold this process's loop 125
#: ms; the flood is the same, and what the robot does with it.
PERIOD = 0.02


def test_a_flood_of_hostile_datagrams_is_refused_and_the_session_loses_nothing() -> None:
    async def main() -> None:
        model = dataclasses.replace(robot_model(EVERY_KIND), period=PERIOD)
        robot = ReferenceRobot(model, RobotSettings(port=0))
        await robot.start()
        local = Simulacrum(robot.model, robot.address)
        await asyncio.wait_for(local.open(), 5)
        session = robot.endpoint.session
        assert session is not None
        # What the local system sends, kept to be replayed: DOWNLINKs carrying OLD.
        sent: list[bytes] = []
        local.tap = sent.append
        local.set_active("armActual", True)
        local.write("arm", OLD)
        assert await until(lambda: local.latest("armActual") == OLD)
        local.tap = None
        old = [data for data in sent if data[TYPE_AT] == PacketType.DOWNLINK][-20:]
        assert old
        local.write("arm", NEW)
        assert await until(lambda: local.latest("armActual") == NEW)
        heard: list[object] = []
        local.listen("armActual", heard.append)  # the robot's arm, every UPLINK

        # A process of its own: a thread of this one would take the loop's turns from the
        # session (one interpreter lock) and the test would measure that, not the robot.
        attacker = multiprocessing.get_context("spawn").Process(
            target=flood, args=(robot.address, old), daemon=True
        )
        attacker.start()
        own = local._transport  # the local system's own socket, for the replays from its address
        assert own is not None
        while attacker.is_alive():  # and the same replays from the local system's own address
            for data in old:
                own.sendto(data)
            await asyncio.sleep(0.005)
        attacker.join(10)
        assert attacker.exitcode == 0
        await asyncio.sleep(0.2)

        # Nothing accepted: the same session, never an old value again, no second session.
        assert robot.endpoint.session is session
        assert local.closed is None
        assert heard
        assert all(values == NEW for values in heard)
        opened = [e for e in robot.history if isinstance(e, events.SessionOpened)]
        assert len(opened) == 1
        assert any(isinstance(e, events.PacketDropped) for e in robot.history)
        # Nothing lost, either way, nor taken twice.
        downlinks = session.wire.tracker.counts
        assert (downlinks.lost, downlinks.duplicates) == (0, 0), downlinks
        uplinks = local.endpoint.received
        assert (uplinks.lost, uplinks.duplicates) == (0, 0), uplinks
        assert not any(isinstance(e, events.LinkLost | events.SessionClosed) for e in local.history)
        await local.aclose()
        robot.stop()

    asyncio.run(asyncio.wait_for(main(), 60))


def test_the_robot_reads_a_flood_several_datagrams_a_wake_up_and_logs_it_once(
    caplog: pytest.LogCaptureFixture,
) -> None:
    """asyncio's datagram transport reads one datagram a turn of the loop: a flood then fills
    the port's buffer and the kernel drops the session's packets with it. The robot reads
    several a wake-up, and says what it drops in a line now and then, not a line each."""

    async def main() -> None:
        robot = ReferenceRobot(robot_model(EVERY_KIND), RobotSettings(port=0))
        await robot.start()
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
            for index in range(300):  # sent while the loop does not run
                sock.sendto(b"\x02" + index.to_bytes(19, "big"), robot.address)

        def dropped() -> int:
            return sum(isinstance(e, events.PacketDropped) for e in robot.history)

        for _ in range(2):
            await asyncio.sleep(0)  # a turn of the loop
        assert dropped() > 2  # more than one a turn
        assert await until(lambda: dropped() == 300)
        robot.stop()

    with caplog.at_level(logging.WARNING, logger="rcmlconf.robot"):
        asyncio.run(asyncio.wait_for(main(), 30))
    lines = [r.getMessage() for r in caplog.records if "dropped" in r.getMessage()]
    assert len(lines) == 1, lines
