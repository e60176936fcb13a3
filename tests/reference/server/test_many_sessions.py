"""Many sessions on one reference server: privilege races, ends of sessions, bad peers."""

from __future__ import annotations

import asyncio

import pytest
from support.robots import ROVER, TESTBOT, robot
from support.servers import Raw, RawSession, run, serving

from rcmlconf.reference.client.adapter import Client, RctpError
from rcmlconf.reference.client.session import Closed, ServerRequest


@run
async def test_of_sessions_racing_for_one_path_exactly_one_wins() -> None:
    async with serving() as server:
        raws = [await RawSession.open(server) for _ in range(20)]
        # Every request leaves before any answer is read (R-RCTP-37).
        for raw, path in zip(raws, ["/drive", "/drive/wheels"] * 10, strict=True):
            await raw.send("ACQUIRE", path)
        statuses = [(await raw.raw.response()).status for raw in raws]
        assert sorted(statuses) == [200] + [471] * 19
        for raw in raws:
            raw.close()


@run
async def test_a_closed_connection_gives_its_privileges_back() -> None:
    async with serving() as server:
        holder = await Client.connect(server.url, robot(TESTBOT))
        other = await Client.connect(server.url, robot(TESTBOT))
        await holder.acquire("/drive")
        with pytest.raises(RctpError, match="471"):
            await other.acquire("/drive/wheels")
        holder._abort()  # the connection drops: no BYE (R-RCTP-36)
        for _ in range(100):
            try:
                await other.acquire("/drive/wheels")
                break
            except RctpError:
                await asyncio.sleep(0.01)
        else:
            raise AssertionError("the privilege of a closed connection was never released")
        await other.close()


@run
async def test_a_silent_session_is_ended_with_bye_timeout() -> None:
    async with serving(session_timeout=1) as server:
        raw = await RawSession.open(server)
        bye = await raw.request(timeout=3.0)
        assert bye is not None
        assert bye.method == "BYE"  # R-RCTP-21
        assert bye.headers.get("Reason") == "timeout"
        assert bye.headers.get("Session") == raw.session
        await raw.answer(bye)
        assert await raw.raw.closed()


@run
async def test_requests_keep_a_session_alive() -> None:
    async with serving(session_timeout=1) as server:
        client = await Client.connect(server.url, robot(TESTBOT))
        # The client refreshes at half the timeout (D-RCTP-11): 2 s is two timeouts.
        assert await client.next_event(timeout=2.0) is None
        assert client.closed is None
        await client.read("/head/control/led")
        await client.close()


@run
async def test_shutdown_says_bye_to_every_session() -> None:
    async with serving() as server:
        clients = [await Client.connect(server.url, robot(TESTBOT)) for _ in range(3)]
        await server.stop()
        for client in clients:
            bye = await client.next_event(timeout=5.0)
            assert bye == ServerRequest("BYE", "*", 200, reason="shutdown")
            assert isinstance(await client.next_event(timeout=5.0), Closed)


@run
async def test_a_broken_peer_loses_its_connection_and_no_one_else_notices() -> None:
    async with serving() as server:
        client = await Client.connect(server.url, robot(TESTBOT))
        await client.acquire("/head")
        for garbage in (
            b"READ / RCTP/2.0\nCSeq: 1\n\n",  # bare LF: framing is lost (R-RCTP-8)
            b"\x00\xff" * 3000,
            b"READ /" + b"a" * 5000 + b" RCTP/2.0\r\n\r\n",
            b"WRITE / RCTP/2.0\r\nCSeq: 1\r\nContent-Length: 99999999999\r\n\r\n",
        ):
            raw = await Raw.open(server)
            await raw.send(garbage)
            answer = await raw.response()
            assert answer.status in (400, 413, 414, 431)
            assert await raw.closed()
        await client.write("/head/control/led", {"led": 7})
        assert await client.read("/head/control/led") == {"led": 7}
        await client.close()


@run
async def test_a_peer_that_stops_reading_is_not_buffered_without_bound() -> None:
    async with serving() as server:
        raw = await RawSession.open(server)
        request = f"READ /head/control/led RCTP/2.0\r\nSession: {raw.session}\r\n"
        # Pipelined requests whose answers are never read: the server stops reading instead
        # of queueing answers, and everyone else is served meanwhile.
        sender = asyncio.create_task(
            raw.raw.send(
                b"".join((request + f"CSeq: {n}\r\n\r\n").encode() for n in range(2, 200_000))
            )
        )
        for _ in range(1000):  # at most 10 s
            paused = [c for c in server.controls.values() if not c.transport.is_reading()]
            if paused:
                break
            await asyncio.sleep(0.01)
        else:
            raise AssertionError("the server never stopped reading from a peer that never reads")
        assert paused[0].transport.get_write_buffer_size() < 1_000_000  # not 200,000 answers
        other = await Client.connect(server.url, robot(TESTBOT))
        assert await other.read("/head/control/led") is not None
        await other.close()
        sender.cancel()
        raw.raw.writer.transport.abort()


@run
async def test_rover_streams_both_ways_while_another_session_watches() -> None:
    async with serving(ROVER) as server:
        driver = await Client.connect(server.url, robot(ROVER))
        watcher = await Client.connect(server.url, robot(ROVER))
        await driver.acquire("/drive")
        await driver.setup("/drive/wheels", "both")
        driver.write_values("/drive/wheels", {"left": 0.3, "right": 0.3})
        await driver.go("/drive/wheels")
        await watcher.setup("/sensors/odometry")
        await watcher.go("/sensors/odometry")
        xs = []
        while len(xs) < 20:
            event = await watcher.next_event(timeout=2.0)
            assert event is not None
            if getattr(event, "path", None) == "/sensors/odometry":
                xs.append(event.values["pose"][0])  # type: ignore[union-attr,index]
        assert xs[-1] > xs[0]  # the written wheel speeds move the robot
        await driver.close()
        await watcher.close()
