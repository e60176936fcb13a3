"""`rcmlconf client` as a user runs it: a real process against the reference server.

The server runs in the test's event loop and the command in its own process, so that neither
waits for the other's loop; every wait is bounded.
"""

from __future__ import annotations

import asyncio
import json
import signal
import socket
import sys
from collections.abc import AsyncIterator, Container
from contextlib import asynccontextmanager
from dataclasses import dataclass
from pathlib import Path

import pytest
from support.robots import CAMERA, ROVER, robot
from support.servers import run, serving

from rcmlconf.cli.client.values import parse_node_value, value_json, value_text
from rcmlconf.errors import ValueTextError
from rcmlconf.rcml.model import DataNode, Permission
from rcmlconf.rctp.fields import Transport, parse_transport
from rcmlconf.rctp.messages import METHODS, Request
from rcmlconf.rctp.reader import MessageReader
from rcmlconf.reference.client.adapter import Client, RctpError
from rcmlconf.reference.client.session import StreamValues
from rcmlconf.reference.server.adapter import ReferenceServer
from rcmlconf.values import ValueType, lookup_type

SCRIPT = Path(sys.executable).parent / "rcmlconf"
COMMAND = [str(SCRIPT)] if SCRIPT.exists() else [sys.executable, "-m", "rcmlconf"]
#: Every wait of these tests is bounded by this many seconds.
BOUND = 20.0


@dataclass
class Done:
    status: int
    out: str
    err: str


def client_args(
    server: ReferenceServer, rcml: Path | None, json_format: bool, args: tuple[str, ...]
) -> list[str]:
    options = ["--rcml", str(rcml)] if rcml is not None else []
    options += ["--format", "json"] if json_format else []
    return [*COMMAND, "client", *options, server.url, *args]


async def client(
    server: ReferenceServer, *args: str, rcml: Path | None = ROVER, json_format: bool = False
) -> Done:
    """`rcmlconf client [--rcml RCML] [--format json] URL ARGS...` to its end."""
    process = await asyncio.create_subprocess_exec(
        *client_args(server, rcml, json_format, args),
        stdout=asyncio.subprocess.PIPE,
        stderr=asyncio.subprocess.PIPE,
    )
    out, err = await asyncio.wait_for(process.communicate(), BOUND)
    done = Done(process.returncode or 0, out.decode(), err.decode())
    assert "Traceback" not in done.err, done.err
    return done


@asynccontextmanager
async def running(
    server: ReferenceServer, *args: str, json_format: bool = False
) -> AsyncIterator[asyncio.subprocess.Process]:
    """A command that runs on (acquire, stream, watch), killed if the test leaves it running."""
    process = await asyncio.create_subprocess_exec(
        *client_args(server, ROVER, json_format, args),
        stdout=asyncio.subprocess.PIPE,
        stderr=asyncio.subprocess.PIPE,
    )
    try:
        yield process
    finally:
        if process.returncode is None:
            process.kill()
            await process.wait()


async def line(stream: asyncio.StreamReader | None) -> str:
    assert stream is not None
    text = (await asyncio.wait_for(stream.readline(), BOUND)).decode()
    assert text, "the command ended first"
    return text


async def interrupted(process: asyncio.subprocess.Process) -> Done:
    """Ctrl-C, then what the command printed to its end."""
    process.send_signal(signal.SIGINT)
    out, err = await asyncio.wait_for(process.communicate(), BOUND)
    return Done(process.returncode or 0, out.decode(), err.decode())


# -- read and write ----------------------------------------------------------------------------


@run
async def test_read_prints_name_value_lines_or_one_json_object() -> None:
    async with serving(CAMERA) as server:
        text = await client(server, "read", "/status/lens", rcml=CAMERA)
        assert text.status == 0, text.err
        assert text.out.splitlines() == ["model = rcmlconf PTZ-1 (simulated)", "moving = false"]
        done = await client(server, "read", "/status/lens", rcml=CAMERA, json_format=True)
        assert json.loads(done.out) == {"model": "rcmlconf PTZ-1 (simulated)", "moving": False}


@run
async def test_a_data_node_of_an_event_access_is_read_through_its_access() -> None:
    async with serving(CAMERA) as server:
        done = await client(server, "read", "/status/lens/moving", rcml=CAMERA)
        assert done.out == "moving = false\n"


@run
async def test_write_then_read_back() -> None:
    async with serving(ROVER) as server:
        wrote = await client(server, "write", "/drive/settings", "maxSpeed=0.3", "mode=2")
        assert (wrote.status, wrote.out, wrote.err) == (0, "", "")
        done = await client(server, "read", "/drive/settings")
        assert done.out.splitlines() == ["maxSpeed = 0.3", "mode = 2"]
        assert (await client(server, "write", "/drive/settings/mode", "0")).status == 0
        done = await client(server, "read", "/drive/settings/mode", json_format=True)
        assert json.loads(done.out) == {"mode": 0}


@run
async def test_an_error_status_exits_1_with_one_line() -> None:
    async with serving(ROVER) as server:
        done = await client(server, "read", "/x")
        assert done.status == 1
        assert done.out == ""
        assert done.err == "rcmlconf client: READ /x: 404 Not Found: no node /x\n"
        done = await client(server, "write", "/drive/settings/mode", "7")
        assert done.status == 1
        assert done.err.startswith("rcmlconf client: WRITE /drive/settings: 422 ")
        done = await client(server, "write", "--no-acquire", "/drive/settings/mode", "1")
        assert done.status == 1
        assert "470 Not Acquired" in done.err


@run
async def test_a_path_another_session_holds_is_refused_with_471() -> None:
    async with serving(ROVER) as server:
        holder = await Client.connect(server.url, robot(ROVER))
        await holder.acquire("/drive")
        done = await client(server, "write", "/drive/settings", "mode=1")
        assert done.status == 1
        assert done.err.startswith(
            "rcmlconf client: ACQUIRE /drive/settings: 471 Acquired by Another Session"
        )
        await holder.close()


@pytest.mark.parametrize(
    ("args", "words"),
    [
        (["read", "/drive/wheels/left"], "use `stream /drive/wheels`"),
        (["write", "/drive/wheels", "left=1"], "use `stream /drive/wheels`"),
        (["write", "/drive/settings/mode", "two"], "'two' is not a decimal integer"),
        (["write", "/drive/settings", "speed=1"], "has no data node 'speed'"),
        (["write", "/drive/settings/mode", "1", "2"], "give one VALUE"),
        (["read", "drive"], "paths are absolute"),
        (["stream", "/drive/settings"], "is not a stream access"),
        (["stream", "/drive/wheels", "--mode", "both"], "give --set NAME=VALUE for one or more"),
        (["stream", "/drive/wheels", "--mode", "both", "--set", "speed=1"], "no data node 'speed'"),
        (["stream", "/sensors/odometry", "--set", "pose=1"], "use --mode write"),
        (["watch", "/drive/wheels"], "is not an event access"),
    ],
)
def test_what_the_model_rules_out_is_a_usage_error(args: list[str], words: str) -> None:
    @run
    async def check() -> None:
        async with serving(ROVER) as server:
            done = await client(server, *args)
            assert done.status == 2
            assert words in done.err

    check()


@run
async def test_no_server_exits_2() -> None:
    with socket.socket() as unused:
        unused.bind(("127.0.0.1", 0))
        port = unused.getsockname()[1]
    process = await asyncio.create_subprocess_exec(
        *COMMAND,
        "client",
        "--rcml",
        str(ROVER),
        f"rctp://127.0.0.1:{port}/rover",
        "read",
        "/drive/settings",
        stderr=asyncio.subprocess.PIPE,
    )
    _, err = await asyncio.wait_for(process.communicate(), BOUND)
    assert process.returncode == 2
    assert err.decode().startswith(f"rcmlconf client: cannot connect to 127.0.0.1:{port}")


# -- the model over HTTP -----------------------------------------------------------------------


@asynccontextmanager
async def serving_files_next_door(rcml: Path = ROVER) -> AsyncIterator[ReferenceServer]:
    """A robot with its files on the port after RCTP's, where the client looks for them."""
    for _ in range(20):
        with socket.socket() as probe:
            probe.bind(("127.0.0.1", 0))
            port = probe.getsockname()[1]
        if port >= 65535:
            continue
        try:
            context = serving(rcml, port=port, http_port=port + 1)
            server = await context.__aenter__()
        except OSError:  # taken meanwhile: try another pair
            continue
        try:
            yield server
        finally:
            await context.__aexit__(None, None, None)
        return
    raise AssertionError("no two free ports in a row")


@run
async def test_without_rcml_the_model_comes_from_the_servers_files() -> None:
    async with serving_files_next_door() as server:
        done = await client(server, "read", "/identity/info", rcml=None)
        assert done.status == 1  # a normal access is not read as a whole: the server says so
        assert "405 Method Not Allowed" in done.err
        done = await client(server, "read", "/identity/info/name", rcml=None)
        assert (done.status, done.out) == (0, "name = rover\n")


@run
async def test_rcml_may_be_a_url() -> None:
    async with serving(ROVER) as server:
        url = f"http://127.0.0.1:{server.http_port}/rover.rcml"
        process = await asyncio.create_subprocess_exec(
            *COMMAND,
            "client",
            "--rcml",
            url,
            server.url,
            "read",
            "/identity/info/name",
            stdout=asyncio.subprocess.PIPE,
        )
        out, _ = await asyncio.wait_for(process.communicate(), BOUND)
        assert (process.returncode, out) == (0, b"name = rover\n")


@run
async def test_without_rcml_or_files_the_message_says_to_pass_rcml() -> None:
    async with serving(ROVER, http_port=None) as server:
        done = await client(server, "read", "/identity/info/name", rcml=None)
        assert done.status == 2
        assert "cannot fetch http://127.0.0.1:" in done.err
        assert "--rcml" in done.err


# -- commands that run on ----------------------------------------------------------------------


@run
async def test_acquire_holds_until_ctrl_c_then_releases() -> None:
    async with serving(ROVER) as server, running(server, "acquire", "/drive") as process:
        assert "acquired /drive" in await line(process.stderr)
        other = await Client.connect(server.url, robot(ROVER))
        with pytest.raises(RctpError, match="471"):
            await other.acquire("/drive/settings")
        done = await interrupted(process)
        assert done.status == 0, done.err
        assert "released /drive" in done.err
        await other.acquire("/drive/settings")
        await other.close()


@run
async def test_acquire_hold_ends_by_itself() -> None:
    async with serving(ROVER) as server:
        done = await client(server, "acquire", "/", "--hold", "0.2")
        assert done.status == 0
        assert done.err.splitlines() == [
            "acquired /; holding it for 0.2 s (Ctrl-C stops sooner)",
            "released /",
        ]


@run
async def test_stream_prints_values_then_a_summary() -> None:
    async with serving(ROVER) as server:
        done = await client(server, "stream", "/sensors/odometry", "--duration", "0.3")
        assert done.status == 0, done.err
        lines = done.out.splitlines()
        assert lines
        assert all(" pose=" in line and " range=" in line for line in lines), lines
        summary = done.err.splitlines()[-1]
        assert summary.startswith(f"/sensors/odometry: {len(lines)} packet")
        assert " lost, " in summary
        assert "clock" in summary


@run
async def test_stream_json_lines_and_writing() -> None:
    async with serving(ROVER) as server:
        done = await client(
            server,
            "stream",
            "/drive/wheels",
            "--mode",
            "both",
            "--set",
            "left=0.25",
            "--set",
            "right=0.25",
            "--duration",
            "0.3",
            json_format=True,
        )
        assert done.status == 0, done.err
        documents = [json.loads(line) for line in done.out.splitlines()]
        assert documents[-1]["event"] == "summary"
        assert documents[-1]["values"] == len(documents) - 1
        assert {d["event"] for d in documents[:-1]} <= {"values"}
        assert all(set(d["values"]) == {"left", "right"} for d in documents[:-1])


CONTROL = "/stream/control"
#: README's example, as written there; the test puts the server's port in place of 7330.
README_STREAM = (
    "client rctp://127.0.0.1:7330/camera stream /stream/control --mode both --set pan=90"
    " --duration 2"
)


async def camera_reaches(
    server: ReferenceServer, axes: dict[str, int], *, point: bool = False
) -> None:
    """Wait until the camera's axes, read on its stream, are `axes` (after writing them there
    as set points, if `point`)."""
    camera = await Client.connect(server.url, robot(CAMERA))
    if point:
        await camera.acquire(CONTROL)
    await camera.setup(CONTROL, "both" if point else "read")
    if point:
        camera.write_values(CONTROL, axes)
    await camera.go(CONTROL)
    async with asyncio.timeout(BOUND):
        while not (
            isinstance(event := await camera.next_event(), StreamValues) and event.values == axes
        ):
            assert event is not None, "the session ended"
    await camera.close()


@run
async def test_readme_stream_writes_pan_and_keeps_the_other_axes() -> None:
    async with serving_files_next_door(CAMERA) as server:
        await camera_reaches(server, {"pan": 0, "tilt": 10, "zoom": 30, "focus": 40}, point=True)
        args = README_STREAM.replace(":7330/", f":{server.port}/").split()
        process = await asyncio.create_subprocess_exec(
            *COMMAND, *args, stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE
        )
        out, err = await asyncio.wait_for(process.communicate(), BOUND)
        assert process.returncode == 0, err
        assert "writing pan=90, and focus=40 tilt=10 zoom=30 as read\n" in err.decode()
        assert out.decode().startswith(tuple(f"{h:02d}:" for h in range(24)))  # values lines
        # The set point stays after the session: the camera turns on to it, the rest unmoved.
        await camera_reaches(server, {"pan": 90, "tilt": 10, "zoom": 30, "focus": 40})


@run
async def test_stream_mode_write_reads_the_values_it_keeps_first() -> None:
    async with serving(CAMERA) as server:
        await camera_reaches(server, {"pan": 15, "tilt": -20, "zoom": 0, "focus": 60}, point=True)
        done = await client(
            server, "stream", CONTROL, "--mode", "write", "--set", "zoom=70", "--duration", "0.5",
            rcml=CAMERA,
        )  # fmt: skip
        assert done.status == 0, done.err
        assert done.out == ""  # mode write shows no values: the ones read were to keep
        assert "writing zoom=70, and focus=60 pan=15 tilt=-20 as read\n" in done.err
        await camera_reaches(server, {"pan": 15, "tilt": -20, "zoom": 70, "focus": 60})


@asynccontextmanager
async def silent_robot(
    methods: list[str], answered: Container[str] = METHODS
) -> AsyncIterator[int]:
    """The port of an RCTP server that answers every request 200 (`methods` lists them), or
    those of the `answered` methods only, and sends nothing on the data stream: a stream's values
    never come."""
    loop = asyncio.get_running_loop()
    udp, _ = await loop.create_datagram_endpoint(
        asyncio.DatagramProtocol, local_addr=("127.0.0.1", 0)
    )
    data_port = udp.get_extra_info("sockname")[1]

    async def session(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        messages = MessageReader()
        while data := await reader.read(65536):
            messages.feed(data)
            while isinstance(request := messages.next_message(), Request):
                methods.append(request.method)
                if request.method not in answered:
                    continue
                fields = [f"CSeq: {request.headers.get('CSeq')}", "Session: silent-robot-1"]
                if request.method == "SETUP":
                    asked = parse_transport(request.headers.get("Transport") or "")
                    given = Transport(asked.client_port, asked.mode, data_port, 0x5113, 1)
                    fields.append(f"Transport: {given}")
                answer = "RCTP/2.0 200 OK\r\n" + "".join(f"{f}\r\n" for f in fields) + "\r\n"
                writer.write(answer.encode())
        writer.close()

    server = await asyncio.start_server(session, "127.0.0.1", 0)
    try:
        async with server:
            yield server.sockets[0].getsockname()[1]
    finally:
        udp.close()


@run
async def test_values_to_keep_that_never_come_end_the_stream_after_timeout() -> None:
    methods: list[str] = []
    async with silent_robot(methods) as port:
        process = await asyncio.create_subprocess_exec(
            *COMMAND, "client", "--timeout", "0.5", "--rcml", str(CAMERA),
            f"rctp://127.0.0.1:{port}/camera", "stream", CONTROL, "--mode", "both",
            "--set", "pan=90", stderr=asyncio.subprocess.PIPE,
        )  # fmt: skip
        _, err = await asyncio.wait_for(process.communicate(), BOUND)
    assert process.returncode == 2, err
    assert err.decode().splitlines()[-1] == (
        "rcmlconf client: /stream/control: no values from the robot within 0.5 s: the values"
        " of focus, tilt, zoom to keep are unknown"
    )
    assert methods == ["CONNECT", "ACQUIRE", "SETUP", "GO", "BYE"]


@run
async def test_timeout_bounds_the_wait_for_each_answer() -> None:
    methods: list[str] = []
    async with silent_robot(methods, answered={"CONNECT"}) as port:
        process = await asyncio.create_subprocess_exec(
            *COMMAND, "client", "--timeout", "0.5", "--rcml", str(CAMERA),
            f"rctp://127.0.0.1:{port}/camera", "read", "/status/lens",
            stderr=asyncio.subprocess.PIPE,
        )  # fmt: skip
        _, err = await asyncio.wait_for(process.communicate(), BOUND)
    assert process.returncode == 2, err
    # It waited 5 s, whatever --timeout said.
    assert err.decode() == "rcmlconf client: READ /status/lens: no answer within 0.5 s\n"
    assert methods == ["CONNECT", "READ", "BYE"]


@run
async def test_watch_prints_the_servers_writes_and_its_bye() -> None:
    async with serving(ROVER) as server, running(server, "watch", "/drive/settings") as process:
        assert "watching /drive/settings" in await line(process.stderr)
        writer = await Client.connect(server.url, robot(ROVER))
        await writer.acquire("/drive/settings")
        await writer.write("/drive/settings", {"maxSpeed": 0.75, "mode": 2})
        assert (await line(process.stdout)).endswith(
            " WRITE /drive/settings maxSpeed=0.75 mode=2\n"
        )
        await writer.close()
        await server.stop()  # BYE to every session, the watcher's too
        out, err = await asyncio.wait_for(process.communicate(), BOUND)
        assert process.returncode == 0, err
        assert out.decode().endswith(" BYE (Reason: shutdown)\n")


@run
async def test_watch_ends_at_ctrl_c() -> None:
    async with serving(ROVER) as server, running(server, "watch", json_format=True) as process:
        notice = await line(process.stderr)
        assert "/drive/settings" in notice
        assert "/sensors/events" in notice
        done = await interrupted(process)
        assert done.status == 0, done.err
        for document in map(json.loads, done.out.splitlines()):
            assert document["event"] == "write"


def test_help_teaches() -> None:
    @run
    async def check() -> None:
        for args in (["client", "--help"], ["client", "rctp://x/", "stream", "--help"]):
            process = await asyncio.create_subprocess_exec(
                *COMMAND, *args, stdout=asyncio.subprocess.PIPE
            )
            out, _ = await asyncio.wait_for(process.communicate(), BOUND)
            assert process.returncode == 0
            assert b"Examples" in out
            assert b"rcmlconf client rctp://127.0.0.1:7330/" in out

    check()


# -- text forms --------------------------------------------------------------------------------


def data_node(type_name: str, count: int = 1, size: int = 0) -> DataNode:
    base = lookup_type(type_name)
    assert base is not None
    return DataNode(f"/a/{type_name}", type_name, ValueType(base, count, size), Permission.READ)


@pytest.mark.parametrize(
    ("type_name", "count", "size", "text", "shown"),
    [
        ("float32", 1, 0, "0.3", "0.3"),
        ("float32", 1, 0, "-2E3", "-2000.0"),
        ("float32", 1, 0, "1e20", "1e+20"),
        ("float64", 1, 0, "0.1", "0.1"),
        ("float64", 1, 0, "INF", "INF"),
        ("float32", 1, 0, "-INF", "-INF"),
        ("float64", 1, 0, "NaN", "NaN"),
        ("bool", 1, 0, "1", "true"),
        ("int8", 1, 0, "-128", "-128"),
        ("uint64", 1, 0, "18446744073709551615", "18446744073709551615"),
        ("bytes", 1, 8, "00ff1A", "00ff1a"),
        ("uint16", 3, 0, "1, 2,3", "1,2,3"),
        ("string", 2, 8, "a, b", "a, b"),
        ("string", 1, 8, "", ""),
    ],
)
def test_values_read_back_as_typed(
    type_name: str, count: int, size: int, text: str, shown: str
) -> None:
    node = data_node(type_name, count, size)
    value = parse_node_value(node, text)
    assert value_text(node, value) == shown
    assert parse_node_value(node, shown) == value or shown == "NaN"


def test_json_holds_what_json_can() -> None:
    assert value_json(data_node("float32"), parse_node_value(data_node("float32"), "0.3")) == 0.3
    assert value_json(data_node("float64"), float("inf")) == "INF"
    assert value_json(data_node("bytes", size=2), b"\x00\xff") == "00ff"
    assert value_json(data_node("int8", count=2), (1, -1)) == [1, -1]


def test_a_robots_string_cannot_steer_the_terminal() -> None:
    assert value_text(data_node("string", size=16), "red\x1b[31m\n") == "red\\x1b[31m\\x0a"


@pytest.mark.parametrize(
    ("type_name", "count", "text", "words"),
    [
        ("uint16", 3, "1,2", "3 comma-separated items needed, not 2"),
        ("int8", 1, "128", "outside the range of int8"),
        ("string", 1, "too long", "longer than size 4"),
    ],
)
def test_a_value_that_is_not_its_nodes_says_so(
    type_name: str, count: int, text: str, words: str
) -> None:
    with pytest.raises(ValueTextError, match=words) as caught:
        parse_node_value(data_node(type_name, count, size=4), text)
    assert str(caught.value).startswith(f"/a/{type_name} (")
