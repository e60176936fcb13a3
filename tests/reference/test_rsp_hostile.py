"""The reference RSP robot under a flood of hostile datagrams on 127.0.0.1, a real session going
on: garbage, packets of the session from another address (its session ID spoofed), and replays
of the session's own packets, from another address and from the local system's own. Nothing of
it is accepted, and the real session loses nothing (issue 18)."""

from __future__ import annotations

import asyncio
import logging
import random
import socket
import threading
import time

import pytest
from support.rsp_models import EVERY_KIND, robot_model
from support.waits import until

from rcmlconf.reference.rsp.robot import ReferenceRobot, RobotSettings
from rcmlconf.reference.rsp.simulacrum import Simulacrum
from rcmlconf.rsp.codec.header import HEADER, PacketType
from rcmlconf.rsp.session import events

OLD = {"shoulder": 10, "elbow": 20, "grip": True}
NEW = {"shoulder": -30, "elbow": 45, "grip": False}
#: Hostile datagrams of each kind, and of each kind in a burst every PACE seconds: about 10,000
#: datagrams a second, bench/hostile_load.py's garbage UDP.
EACH = 3000
BURST, PACE = 10, 0.003
#: Where a header's type and sequence number are (D-RSP-10).
TYPE_AT, SEQUENCE_AT = 4, 5


def _spoofed(packet: bytes, ahead: int) -> bytes:
    """`packet` with its sequence number `ahead` of its own: newer, were it the session's."""
    (sequence,) = HEADER.unpack_from(packet)[4:5]
    data = bytearray(packet)
    data[SEQUENCE_AT : SEQUENCE_AT + 2] = ((sequence + ahead) & 0xFFFF).to_bytes(2, "big")
    return bytes(data)


def _flood(robot: tuple[str, int], old: list[bytes]) -> None:
    """From another address: garbage, the session's packets made newer (a spoofed session ID),
    and its old packets replayed, interleaved; in bursts, so that the flood fits the robot's
    receive buffer on any system (net.core.rmem_max may be 200 KiB): the test is of what the
    robot does with the datagrams, not of what the kernel drops."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("127.0.0.2", 0))
        for index in range(EACH):
            if index % BURST == 0:
                time.sleep(PACE)
            replay = old[index % len(old)]
            for data in (
                random.randbytes(random.randrange(1, 200)),
                _spoofed(replay, 1 + index),
                replay,
            ):
                sock.sendto(data, robot)  # blocking: none lost here for want of buffer


def test_a_flood_of_hostile_datagrams_is_refused_and_the_session_loses_nothing() -> None:
    async def main() -> None:
        robot = ReferenceRobot(robot_model(EVERY_KIND), RobotSettings(port=0))
        await robot.start()
        local = Simulacrum(robot.model, robot.address)
        await asyncio.wait_for(local.open(), 5)
        session = robot.endpoint.session
        assert session is not None
        # What the local system sends, kept to be replayed: DOWNLINKs carrying OLD.
        transport = local._transport
        assert transport is not None
        send = transport.sendto
        sent: list[bytes] = []

        def keep(data: bytes, addr: object = None) -> None:
            sent.append(bytes(data))
            send(data)

        transport.sendto = keep  # type: ignore[method-assign]
        local.set_active("armActual", True)
        local.write("arm", OLD)
        assert await until(lambda: local.latest("armActual") == OLD)
        old = [data for data in sent if data[TYPE_AT] == PacketType.DOWNLINK][-20:]
        assert old
        local.write("arm", NEW)
        assert await until(lambda: local.latest("armActual") == NEW)
        heard: list[object] = []
        local.listen("armActual", heard.append)  # the robot's arm, every UPLINK

        flood = threading.Thread(target=_flood, args=(robot.address, old), daemon=True)
        flood.start()
        while flood.is_alive():  # and the same replays from the local system's own address
            for data in old:
                send(data)
            await asyncio.sleep(0.005)
        flood.join(10)
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
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as flood:
            for index in range(300):  # sent while the loop does not run
                flood.sendto(b"\x02" + index.to_bytes(19, "big"), robot.address)

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
