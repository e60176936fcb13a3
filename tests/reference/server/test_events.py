"""Data-change events (D-RCTP-27): pushed as server WRITEs to the sessions that watch."""

from __future__ import annotations

from support.robots import TESTBOT, robot
from support.servers import RawSession, run, serving

from rcmlconf.rcml.model import DataNode
from rcmlconf.rctp.bodies import ValuesCodec
from rcmlconf.reference.client.adapter import Client
from rcmlconf.reference.client.session import ServerRequest

SETTINGS = "/drive/settings"


async def watching(server_url: str) -> Client:
    client = await Client.connect(server_url, robot(TESTBOT))
    await client.setup(SETTINGS)
    await client.go(SETTINGS)
    return client


@run
async def test_a_change_is_pushed_to_watchers_but_not_to_its_writer() -> None:
    async with serving() as server:
        writer, watcher = await watching(server.url), await watching(server.url)
        await writer.acquire("/drive")
        await writer.write(SETTINGS, {"mode": 2, "label": "fast"})
        pushed = await watcher.next_event(timeout=2.0)
        assert pushed == ServerRequest("WRITE", SETTINGS, 200, {"label": "fast", "mode": 2})
        assert await writer.next_event(timeout=0.3) is None  # R-RCTP-54
        await watcher.pause(SETTINGS)
        await writer.write(SETTINGS, {"mode": 3})
        assert await watcher.next_event(timeout=0.3) is None  # paused: nothing is pushed
        await writer.close()
        await watcher.close()


@run
async def test_no_more_than_four_pushes_wait_and_later_changes_merge() -> None:
    async with serving() as server:
        raw = await RawSession.open(server)
        for method in ("SETUP", "GO"):
            assert (await raw.ask(method, SETTINGS)).status == 200
        writer = await Client.connect(server.url, robot(TESTBOT))
        await writer.acquire("/drive")
        for mode in (0, 1, 2, 3, 0, 1, 2, 3, 1):  # 0 is the first value: no change
            await writer.write(SETTINGS, {"mode": mode})
        pushes = []
        while (push := await raw.request(timeout=0.3)) is not None:
            pushes.append(push)
        assert len(pushes) == 4  # R-RCTP-55: none of them is answered
        for push in pushes:
            await raw.answer(push)
        merged = await raw.request(timeout=2.0)
        assert merged is not None
        assert merged.headers.get("Nodes") == "mode"
        mode = robot(TESTBOT).node(SETTINGS + "/mode")
        assert isinstance(mode, DataNode)
        assert ValuesCodec([mode], SETTINGS, "R-RCTP-32").decode(merged.body) == {"mode": 1}
        assert await raw.request(timeout=0.3) is None  # the last five changes became one WRITE
        raw.close()
        await writer.close()


@run
async def test_a_client_that_refuses_a_push_keeps_its_session() -> None:
    async with serving() as server:
        raw = await RawSession.open(server)
        for method in ("SETUP", "GO"):
            await raw.ask(method, SETTINGS)
        writer = await Client.connect(server.url, robot(TESTBOT))
        await writer.acquire("/drive")
        await writer.write(SETTINGS, {"enabled": True})
        push = await raw.request()
        assert push is not None
        await raw.answer(push, 400, "Bad Request")
        assert (await raw.ask("READ", SETTINGS)).status == 200
        raw.close()
        await writer.close()
