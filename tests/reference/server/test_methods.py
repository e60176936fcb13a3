"""Every method against the reference server on loopback, and each status it answers wrong ones
with (D-RCTP-25's order), through the reference client or as raw bytes."""

from __future__ import annotations

from dataclasses import dataclass, field

import pytest
from support.robots import TESTBOT, robot
from support.servers import Raw, RawSession, run, serving

from rcmlconf.rctp.bodies import ValuesCodec
from rcmlconf.rctp.messages import VALUES_TYPE
from rcmlconf.reference.client.adapter import Client, RctpError


def body_of(path: str, value: object) -> bytes:
    node = robot(TESTBOT).node(path)
    return ValuesCodec([node], path, "R-RCTP-28").encode({node.name: value})  # type: ignore[list-item,union-attr,dict-item]


@dataclass
class Step:
    method: str
    target: str
    headers: list[tuple[str, str]] = field(default_factory=list)
    body: bytes = b""


VALUES = [("Content-Type", VALUES_TYPE)]
TRANSPORT_WRITE = [("Transport", "udp;client_port=40000;mode=write")]


# (name, steps answered 200 first, the step under test, status, Allow or None)
REFUSALS = [
    ("no node", [], Step("READ", "/head/nothing"), 404, None),
    ("READ of a group", [], Step("READ", "/head"), 405, "ACQUIRE, RELEASE"),
    (
        "READ of a stream access",
        [],
        Step("READ", "/drive/wheels"),
        405,
        "ACQUIRE, RELEASE, SETUP, GO, PAUSE, STOP",
    ),
    (
        "READ of an event's data node",
        [],
        Step("READ", "/drive/settings/mode"),
        405,
        "ACQUIRE, RELEASE",
    ),
    ("SETUP of a normal access", [], Step("SETUP", "/head/control"), 405, "ACQUIRE, RELEASE"),
    ("BYE of a node", [], Step("BYE", "/head/control/led"), 405, "ACQUIRE, RELEASE, READ, WRITE"),
    ("READ without r", [], Step("READ", "/head/control/say"), 403, None),
    (
        "WRITE without w",
        [Step("ACQUIRE", "/head")],
        Step("WRITE", "/head/control/serial", VALUES, body_of("/head/control/serial", 1)),
        403,
        None,
    ),
    ("permission none", [], Step("READ", "/head/control/pose"), 403, None),
    (
        "WRITE not acquired",
        [],
        Step("WRITE", "/head/control/led", VALUES, body_of("/head/control/led", 1)),
        470,
        None,
    ),
    ("RELEASE not acquired", [], Step("RELEASE", "/head"), 470, None),
    (
        "RELEASE below what is held",
        [Step("ACQUIRE", "/head")],
        Step("RELEASE", "/head/control"),
        470,
        None,
    ),
    (
        "WRITE without Content-Length",
        [Step("ACQUIRE", "/head")],
        Step("WRITE", "/head/control/led", VALUES),
        411,
        None,
    ),
    (
        "WRITE of another type",
        [Step("ACQUIRE", "/head")],
        Step("WRITE", "/head/control/led", [("Content-Type", "text/plain")], b"12345"),
        415,
        None,
    ),
    (
        "WRITE cut short",
        [Step("ACQUIRE", "/head")],
        Step("WRITE", "/head/control/led", VALUES, b"\x00\x01"),
        422,
        None,
    ),
    (
        "WRITE out of range",
        [Step("ACQUIRE", "/head")],
        Step("WRITE", "/head/control/led", VALUES, body_of("/head/control/led", 256)),
        422,
        None,
    ),
    (
        "event WRITE without Nodes",
        [Step("ACQUIRE", "/drive")],
        Step("WRITE", "/drive/settings", VALUES, b"\x01"),
        400,
        None,
    ),
    (
        "Nodes out of order",
        [],
        Step("READ", "/drive/settings", [("Nodes", "mode, enabled")]),
        400,
        None,
    ),
    ("Nodes naming no node", [], Step("READ", "/drive/settings", [("Nodes", "speed")]), 400, None),
    ("SETUP without Transport", [], Step("SETUP", "/drive/wheels"), 461, None),
    (
        "SETUP without client_port",
        [],
        Step("SETUP", "/drive/wheels", [("Transport", "udp")]),
        461,
        None,
    ),
    (
        "SETUP naming the server's part",
        [],
        Step("SETUP", "/drive/wheels", [("Transport", "udp;client_port=1;tag=00000001")]),
        461,
        None,
    ),
    (
        "SETUP of a bad Transport",
        [],
        Step("SETUP", "/drive/wheels", [("Transport", "tcp")]),
        400,
        None,
    ),
    (
        "SETUP for writing, not acquired",
        [],
        Step("SETUP", "/drive/wheels", TRANSPORT_WRITE),
        470,
        None,
    ),
    (
        "SETUP for writing what cannot be written",
        [Step("ACQUIRE", "/")],
        Step("SETUP", "/sensors/range", TRANSPORT_WRITE),
        403,
        None,
    ),
    ("GO before SETUP", [], Step("GO", "/drive/wheels"), 455, None),
    (
        "RELEASE under a writing stream",
        [Step("ACQUIRE", "/drive"), Step("SETUP", "/drive/wheels", TRANSPORT_WRITE)],
        Step("RELEASE", "/drive"),
        455,
        None,
    ),
    (
        "RELEASE * under a writing stream",
        [Step("ACQUIRE", "/drive"), Step("SETUP", "/drive/wheels", TRANSPORT_WRITE)],
        Step("RELEASE", "*"),
        455,
        None,
    ),
]


@pytest.mark.parametrize(
    ("before", "step", "status", "allow"),
    [pytest.param(*case[1:], id=case[0]) for case in REFUSALS],
)
@run
async def test_a_wrong_request_gets_its_status_and_the_session_goes_on(
    before: list[Step], step: Step, status: int, allow: str | None
) -> None:
    async with serving() as server:
        session = await RawSession.open(server)
        for earlier in before:
            assert (await session.ask(**vars(earlier))).status == 200, earlier
        answer = await session.ask(**vars(step))
        assert answer.status == status, answer.body
        assert answer.headers.get("Allow") == allow
        if status != 200:
            assert answer.headers.get("Content-Type") == "text/plain; charset=utf-8"
        # The session goes on (D-RCTP-10).
        assert (await session.ask("READ", "/head/control/led")).status == 200
        session.close()


@run
async def test_connect_names_a_robot_of_the_server() -> None:
    async with serving() as server:
        raw = await Raw.open(server)
        await raw.send(b"CONNECT /elsewhere RCTP/2.0\r\nCSeq: 1\r\n\r\n")
        assert (await raw.response()).status == 404
        await raw.send(b"CONNECT / RCTP/2.0\r\nCSeq: 2\r\n\r\n")
        answer = await raw.response()
        assert answer.status == 200
        session = answer.headers.get("Session") or ""
        assert session.endswith(";timeout=60")  # R-RCTP-18
        assert 8 <= len(session.split(";")[0]) <= 64
        # A refresh answers the same session (R-RCTP-22).
        sid = session.split(";")[0]
        await raw.send(f"CONNECT / RCTP/2.0\r\nCSeq: 3\r\nSession: {sid}\r\n\r\n".encode())
        assert (await raw.response()).headers.get("Session") == session
        raw.close()


@run
async def test_normal_access_reads_and_writes_one_node() -> None:
    async with serving() as server:
        client = await Client.connect(server.url, robot(TESTBOT))
        await client.acquire("/head")
        await client.write("/head/control/led", {"led": 200})
        assert await client.read("/head/control/led") == {"led": 200}
        await client.write("/head/control/say", {"say": "héllo"})  # write-only: written, not read
        with pytest.raises(RctpError, match="403"):
            await client.read("/head/control/say")
        await client.release("/head")
        with pytest.raises(RctpError, match="470"):
            await client.write("/head/control/led", {"led": 1})
        await client.close()


@run
async def test_event_access_writes_all_or_nothing() -> None:
    async with serving() as server:
        client = await Client.connect(server.url, robot(TESTBOT))
        await client.acquire("/drive/settings")
        await client.write("/drive/settings", {"mode": 2, "enabled": True, "label": "fast"})
        assert await client.read("/drive/settings") == {
            "enabled": True,
            "label": "fast",
            "mode": 2,
        }
        with pytest.raises(RctpError, match="422"):  # mode 9 is out of range: nothing changes
            await client.write("/drive/settings", {"mode": 9, "label": "slow"})
        assert await client.read("/drive/settings", ["label", "mode"]) == {
            "label": "fast",
            "mode": 2,
        }
        await client.close()


@run
async def test_stream_and_event_accesses_go_through_their_states() -> None:
    async with serving() as server:
        client = await Client.connect(server.url, robot(TESTBOT))
        for path, mode in (("/sensors/bumpers", "read"), ("/sensors/range", "read")):
            await client.setup(path, mode)
            await client.setup(path, mode)  # again, in ready: allowed (D-RCTP-14)
            await client.go(path)
            await client.go(path)
            with pytest.raises(RctpError, match="455"):
                await client.setup(path, mode)  # not while playing
            await client.pause(path)
            await client.pause(path)
            await client.stop(path)
            with pytest.raises(RctpError, match="455"):
                await client.stop(path)
        await client.close()


@run
async def test_release_star_gives_everything_back() -> None:
    async with serving() as server:
        first = await Client.connect(server.url, robot(TESTBOT))
        second = await Client.connect(server.url, robot(TESTBOT))
        await first.acquire("/head")
        await first.acquire("/drive/settings")
        await first.release("*")
        await second.acquire("/")
        await first.close()
        await second.close()


@run
async def test_bye_ends_the_session_and_closes_the_connection() -> None:
    async with serving() as server:
        session = await RawSession.open(server)
        answer = await session.ask("BYE", "*")
        assert answer.status == 200
        await session.raw.send(b"READ /head/control/led RCTP/2.0\r\nCSeq: 3\r\n\r\n")
        assert await session.raw.closed()


@run
async def test_a_write_takes_its_media_type_in_any_letter_case() -> None:
    """D-RCTP-30: `Application/RCTP-Values` is `application/rctp-values` (R-RCTP-59)."""
    async with serving() as server:
        session = await RawSession.open(server)
        assert (await session.ask("ACQUIRE", "/head")).status == 200
        typed = [("Content-Type", "Application/RCTP-Values")]
        answer = await session.ask("WRITE", "/head/control/led", typed, (7).to_bytes(4, "big"))
        assert answer.status == 200, answer.body
        read = await session.ask("READ", "/head/control/led")
        assert read.body == (7).to_bytes(4, "big")
        session.close()
