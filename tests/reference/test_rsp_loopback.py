"""The reference RSP robot and the simulacrum over real UDP sockets on 127.0.0.1."""

from __future__ import annotations

import asyncio
import threading

import pytest
from support.rsp_models import EVERY_KIND, robot_model

from rcmlconf.reference.rsp.robot import ReferenceRobot, RobotSettings
from rcmlconf.reference.rsp.simulacrum import NoSession, Simulacrum
from rcmlconf.rsp.codec import Encryption
from rcmlconf.rsp.session import events

PSK = bytes(range(32))
ARM = {"shoulder": 10, "elbow": 20, "grip": True}


async def robot_on_loopback(**settings: object) -> ReferenceRobot:
    robot = ReferenceRobot(
        robot_model(EVERY_KIND),
        RobotSettings(port=0, **settings),  # type: ignore[arg-type]
    )
    await robot.start()
    return robot


def test_the_simulacrum_drives_the_robot_and_reads_its_monitor() -> None:
    async def main() -> None:
        robot = await robot_on_loopback()
        local = Simulacrum(robot.model, robot.address)
        opened = await asyncio.wait_for(local.open(), 5)
        assert opened.period == pytest.approx(0.005)
        heard: list[object] = []
        local.listen("armActual", heard.append)
        local.write("arm", ARM)
        local.set_active("armActual", True)
        beep = local.issue("beep", {"tone": 440})
        for _ in range(200):
            await asyncio.sleep(0.01)
            if local.latest("armActual") == ARM and robot.history:
                break
        assert local.latest("armActual") == ARM
        assert heard[-1] == ARM
        assert events.OccurrenceReceived("beep", beep, {"tone": 440}) in robot.history
        await local.aclose()
        await asyncio.sleep(0.05)
        assert robot.endpoint.session is None  # BYE reached it
        robot.stop()

    asyncio.run(main())


def test_an_encrypted_session_over_udp() -> None:
    async def main() -> None:
        robot = await robot_on_loopback(
            encryptions=frozenset({Encryption.CHACHA20_POLY1305}), psk=PSK
        )
        local = Simulacrum(
            robot.model, robot.address, encryption=Encryption.CHACHA20_POLY1305, psk=PSK
        )
        await asyncio.wait_for(local.open(), 5)
        local.write("arm", ARM)
        local.set_active("armActual", True)
        for _ in range(200):
            await asyncio.sleep(0.01)
            if local.latest("armActual") == ARM:
                break
        assert local.latest("armActual") == ARM
        wrong = Simulacrum(robot.model, robot.address, encryption=Encryption.NONE)
        with pytest.raises(NoSession, match="encryption not offered"):
            await wrong.open()
        await local.aclose()
        robot.stop()

    asyncio.run(main())


def test_no_robot_means_no_session() -> None:
    async def main() -> None:
        # A port nobody listens on: ICMP unreachable or silence, then the HELLOs give up.
        with pytest.raises(NoSession):
            await Simulacrum(robot_model(EVERY_KIND), ("127.0.0.1", 9)).open(timeout=0.3)

    asyncio.run(main())


def test_blocking_reads_from_another_thread() -> None:
    """The Robot Environment Data Buffer: read() waits for a newer value, or times out."""
    loop = asyncio.new_event_loop()
    robot = ReferenceRobot(robot_model(EVERY_KIND), RobotSettings(port=0))
    thread = threading.Thread(target=loop.run_forever, daemon=True)
    loop.run_until_complete(robot.start())
    thread.start()
    try:
        local = Simulacrum.start(robot.model, robot.address)
        with pytest.raises(TimeoutError):
            local.read("armActual", timeout=0.1)  # not requested: nothing comes
        local.write("arm", ARM)
        local.set_active("armActual", True)
        # The first values may be from before the robot applied the write.
        seen = [local.read("armActual", timeout=5) for _ in range(50)]
        assert ARM in seen
        assert seen[-1] == ARM  # each read waits for a newer value, and they settle
        local.stop()
    finally:
        loop.call_soon_threadsafe(robot.stop)
        loop.call_soon_threadsafe(loop.stop)
        thread.join(5)


def test_a_read_the_session_s_end_cuts_short_says_why_in_words() -> None:
    """When the robot says BYE, a waiting read ends with NoSession, which says so in words, not
    as the event's repr ("SessionClosed(reason=<ByeReason.SHUTDOWN: 2>, by_peer=True)")."""

    async def main() -> None:
        robot = await robot_on_loopback()
        local = Simulacrum(robot.model, robot.address)
        await asyncio.wait_for(local.open(), 5)
        local.set_active("armActual", True)
        reading = asyncio.get_running_loop().run_in_executor(
            None, lambda: [local.read("armActual", timeout=5) for _ in range(10**4)]
        )
        await asyncio.sleep(0.05)
        robot.stop()
        with pytest.raises(NoSession) as ended:
            await asyncio.wait_for(reading, 5)
        assert str(ended.value) == "the robot ended the session: shutdown"
        assert await asyncio.wait_for(local.ended(), 5) == local.closed
        await local.aclose()

    asyncio.run(main())


def test_a_new_session_keeps_its_own_pace_not_the_one_before() -> None:
    """After a session at T = 1.2 s ends, the next one, at the model's period, gets its first
    control tick within its own period (it had waited out the old 1.2 s)."""

    async def main() -> None:
        robot = await robot_on_loopback()
        slow = Simulacrum(robot.model, robot.address, period=1.2)
        await asyncio.wait_for(slow.open(), 5)
        await asyncio.sleep(0.1)  # a tick at 1.2 s is due now
        await slow.aclose()
        fast = Simulacrum(robot.model, robot.address)
        opened = await asyncio.wait_for(fast.open(), 5)
        now = asyncio.get_running_loop().time()
        assert robot._tick_at <= now + opened.period
        await fast.aclose()
        robot.stop()

    asyncio.run(main())
