"""The reference implementations' faults (`rcmlconf.reference.faults`): each one changes what the
server or the RSP robot does, as its description says, and without faults they do what the specs
ask. Each server fault has a scenario over loopback, run on a clean server and on a faulty one;
each robot fault one on the sans-IO robot endpoint, on a simulated clock."""

from __future__ import annotations

import asyncio
import inspect
import re
import socket
from collections.abc import Awaitable, Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest
from click.testing import CliRunner
from support.robots import TESTBOT
from support.rsp_models import robot_model
from support.servers import TEST_BOUND, Raw, RawSession, serving

from rcmlconf.cli.robot import robot as robot_command
from rcmlconf.cli.serve import serve as serve_command
from rcmlconf.rcml.model import AccessNode, DataNode
from rcmlconf.rctp.datastream.endpoint import Endpoint
from rcmlconf.rctp.datastream.flow import (
    Direction,
    FlowMessage,
    HeartbeatAck,
    HeartbeatRequest,
    IntervalSet,
    encode_flow,
)
from rcmlconf.rctp.datastream.packets import (
    FlowPayload,
    Packet,
    PayloadType,
    pull_packet,
    push_datagram,
)
from rcmlconf.rctp.datastream.values import stream_codec
from rcmlconf.rctp.fields import parse_transport
from rcmlconf.rctp.messages import Request, Response
from rcmlconf.reference.faults import (
    CONTROL_FAULTS,
    DESCRIPTIONS,
    ROBOT_FAULTS,
    SERVER_FAULTS,
    STREAM_FAULTS,
    Fault,
    names,
    rewrite_control,
)
from rcmlconf.reference.rsp.faulty_session import FaultyRobotEndpoint
from rcmlconf.reference.rsp.robot import ReferenceRobot, RobotSettings
from rcmlconf.reference.server.adapter import ReferenceServer, ServerSettings
from rcmlconf.reference.server.faulty_privileges import FaultyPrivileges
from rcmlconf.reference.server.faulty_robot import FaultyRobot
from rcmlconf.reference.server.faulty_session import FaultySession
from rcmlconf.reference.server.faulty_stream import FaultyEndpoint
from rcmlconf.reference.server.privileges import Privileges
from rcmlconf.reference.server.robot import Robot
from rcmlconf.reference.server.session import ServerSession
from rcmlconf.rsp.codec import (
    CLEAR_BUFFER,
    ByeReason,
    Encryption,
    Header,
    Hello,
    Item,
    MapBody,
    PacketType,
    pull_header,
    push_header,
)
from rcmlconf.rsp.codec import Packet as RspPacket
from rcmlconf.rsp.codec.bodies import push_session_body
from rcmlconf.rsp.reliable import INITIAL_RTO_PERIODS
from rcmlconf.rsp.security import Direction as RspDirection
from rcmlconf.rsp.session.robot import RobotEndpoint
from rcmlconf.rsp.session.wire import SessionWire
from rcmlconf.specs import requirements
from rcmlconf.values import Value

# -- the faults themselves -------------------------------------------------------------------------


def test_every_fault_is_described_kebab_case_and_names_requirements_of_specs() -> None:
    known = requirements()
    assert set(DESCRIPTIONS) == set(Fault)
    for fault in Fault:
        assert re.fullmatch(r"[a-z0-9]+(-[a-z0-9]+)*", fault.value), fault
        assert fault.implementation in ("server", "robot")
        assert fault.description, fault
        assert "\n" not in fault.description, fault
        assert fault.requirements, fault
        for requirement in fault.requirements:
            assert requirement in known, (fault, requirement)
        # A server's faults may break RCML's rules for implementations too (R-RCML-29, -30).
        protocol = ("R-RCTP-", "R-RCML-") if fault.implementation == "server" else ("R-RSP-",)
        assert all(r.startswith(protocol) for r in fault.requirements), fault
    assert len(SERVER_FAULTS) >= 20
    assert len(ROBOT_FAULTS) >= 6
    assert set(Fault) == SERVER_FAULTS | ROBOT_FAULTS
    assert CONTROL_FAULTS | STREAM_FAULTS <= SERVER_FAULTS


def test_without_faults_nothing_changes() -> None:
    assert ServerSettings().faults == frozenset()
    assert type(ReferenceRobot(robot_model(), RobotSettings()).endpoint) is RobotEndpoint
    data = b"RCTP/2.0 404 Not Found\r\nCSeq: 3\r\n\r\nREAD /x RCTP/2.0\r\nCSeq: 1\r\n\r\n"
    assert rewrite_control(data, frozenset()) == data


#: The server's core modules. Its faults are subclasses of their classes, not checks in them.
SERVER_CORE = ("session.py", "robot.py", "privileges.py")


def test_the_servers_core_knows_no_fault() -> None:
    folder = Path(inspect.getfile(ServerSession)).parent
    for name in SERVER_CORE:
        found = re.search(r".*(?i:\bfault).*", (folder / name).read_text())
        assert found is None, f"{name}: {found and found.group().strip()}"


def test_a_server_makes_the_faulty_classes_only_with_faults() -> None:
    async def main() -> list[tuple[type, ...]]:
        made = []
        for faults in (frozenset(), frozenset({Fault.PAUSE_IGNORED})):
            async with serving(TESTBOT, faults=faults) as server:
                session = await RawSession.open(server)
                (control,) = server.controls.values()
                robot = server.robot
                made.append((type(robot), type(robot.privileges), type(control.session)))
                session.close()
        return made

    made = asyncio.run(asyncio.wait_for(main(), TEST_BOUND))
    assert made == [
        (Robot, Privileges, ServerSession),
        (FaultyRobot, FaultyPrivileges, FaultySession),
    ]


def test_rewrite_control_changes_only_what_its_faults_say() -> None:
    body = b"no node /x"
    error = (
        b"RCTP/2.0 404 Not Found\r\nCSeq: 3\r\nSession: abcdefgh\r\nContent-Type: text/plain; "
        b"charset=utf-8\r\nContent-Length: 10\r\n\r\n" + body
    )
    bye = b"BYE * RCTP/2.0\r\nCSeq: 4\r\nReason: timeout\r\nSession: abcdefgh\r\n\r\n"
    both = error + bye

    def rewritten(*faults: Fault) -> bytes:
        return rewrite_control(both, frozenset(faults))

    assert rewritten(Fault.WRONG_STATUS).startswith(b"RCTP/2.0 400 Bad Request\r\nCSeq: 3\r\n")
    assert rewritten(Fault.WRONG_STATUS).endswith(body + bye)
    assert b"CSeq: 3" not in rewritten(Fault.NO_CSEQ_ECHO)
    assert b"CSeq: 4" in rewritten(Fault.NO_CSEQ_ECHO)  # requests keep theirs
    assert rewritten(Fault.NO_TIMEOUT_BYE) == error
    assert b"Content-Type" not in rewritten(Fault.NO_CONTENT_TYPE)
    lf = rewritten(Fault.BARE_LF)
    assert b"\r" not in lf.replace(body, b"")
    assert lf.count(b"\n\n") == 2
    assert rewritten(Fault.UNKNOWN_METHOD_400) == both  # no 501 here


def test_the_cli_offers_each_implementations_faults() -> None:
    runner = CliRunner()
    serve = runner.invoke(serve_command, ["--help"], terminal_width=400)
    robot = runner.invoke(robot_command, ["--help"], terminal_width=400)
    assert "conformance harness" in serve.output
    assert "conformance harness" in robot.output
    assert names("server") == [f.value for f in Fault if f in SERVER_FAULTS]
    wrong = runner.invoke(serve_command, ["--fault", "ack-next-id", str(TESTBOT)])
    assert wrong.exit_code == 2  # a robot's fault is not the server's
    assert "ack-next-id" in wrong.output
    wrong = runner.invoke(robot_command, ["--fault", "bare-lf", "x.rmodel"])
    assert wrong.exit_code == 2


def test_a_faulty_server_says_so_at_start(caplog: pytest.LogCaptureFixture) -> None:
    async def main() -> None:
        async with serving(TESTBOT, faults=frozenset({Fault.BARE_LF})):
            pass

    asyncio.run(asyncio.wait_for(main(), TEST_BOUND))
    warned = [r for r in caplog.records if r.levelname == "WARNING"]
    assert any("bare-lf" in r.getMessage() for r in warned)


# -- the server: a scenario per fault --------------------------------------------------------------

SETTINGS = "/drive/settings"
WHEELS = "/drive/wheels"
RANGE = "/sensors/range"


def nodes(access: str, *names: str) -> tuple[DataNode, ...]:
    from support.robots import robot

    node = robot(TESTBOT).node(access)
    assert isinstance(node, AccessNode)
    return tuple(n for n in node.data if n.name in names)


def settings_body(server: ReferenceServer, **values: Value) -> tuple[list[tuple[str, str]], bytes]:
    """The Nodes field and body of a WRITE of /drive/settings."""
    chosen = nodes(SETTINGS, *values)
    codec = server.robot.codec(SETTINGS, chosen)
    nodes_field = ", ".join(n.name for n in chosen)
    body = codec.encode({n.name: values[n.name] for n in chosen})
    return [("Nodes", nodes_field), ("Content-Type", "application/rctp-values")], body


async def answer(session: RawSession, timeout: float = 2.0) -> tuple[Response, list[Request]]:
    """The response to the request just sent, and the server's requests that came before it."""
    before: list[Request] = []
    while True:
        message = await session.raw.message(timeout)
        assert message is not None, "the server closed the connection"
        if isinstance(message, Response):
            return message, before
        before.append(message)


async def ask(
    session: RawSession, method: str, target: str, headers: Any = (), body: bytes = b""
) -> Response:
    await session.send(method, target, headers, body)
    return (await answer(session))[0]


async def requests(session: RawSession, seconds: float) -> list[Request]:
    """The server's requests within `seconds`, unanswered."""
    found: list[Request] = []
    deadline = asyncio.get_running_loop().time() + seconds
    while (left := deadline - asyncio.get_running_loop().time()) > 0:
        try:
            message = await session.raw.message(left)
        except TimeoutError:
            break
        if message is None:
            break
        assert isinstance(message, Request), message
        found.append(message)
    return found


async def raw_head(raw: Raw, timeout: float = 2.0) -> bytes:
    """The bytes of the first message's head, however its lines end."""
    data = b""
    while b"\n\n" not in data.replace(b"\r\n", b"\n"):
        chunk = await asyncio.wait_for(raw.reader.read(65536), timeout)
        if not chunk:
            break
        data += chunk
    return data


class Udp:
    """The client's end of a data stream: one socket on 127.0.0.1."""

    def __init__(self) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.setblocking(False)
        self.port: int = self.sock.getsockname()[1]
        self.sequence = 1000

    async def recv(self, timeout: float = 1.0) -> bytes | None:
        loop = asyncio.get_running_loop()
        try:
            return await asyncio.wait_for(loop.sock_recv(self.sock, 65536), timeout)
        except TimeoutError:
            return None

    async def packets(self, seconds: float) -> list[Packet]:
        found = []
        deadline = asyncio.get_running_loop().time() + seconds
        while (left := deadline - asyncio.get_running_loop().time()) > 0:
            data = await self.recv(left)
            if data is None:
                break
            found.append(pull_packet(data))
        return found

    def send(
        self,
        server: ReferenceServer,
        tag: int,
        payloads: list[tuple[int, bytes, int]],
        sequence: int | None = None,
    ) -> None:
        if sequence is None:
            self.sequence += 1
            sequence = self.sequence
        datagram = push_datagram(sequence, tag, 0, payloads)
        self.sock.sendto(datagram, ("127.0.0.1", server.data_port))

    def close(self) -> None:
        self.sock.close()


async def setup(session: RawSession, udp: Udp, path: str, mode: str) -> tuple[int, int]:
    """SETUP of a stream access: the session's tag and the stream's id."""
    transport = [("Transport", f"udp;client_port={udp.port};mode={mode}")]
    answered = await ask(session, "SETUP", path, transport)
    assert answered.status == 200, answered
    given = parse_transport(answered.headers.get("Transport") or "")
    assert given.tag is not None
    assert given.stream is not None
    return given.tag, given.stream


async def flow_answers(udp: Udp, count: int) -> list[FlowMessage]:
    found: list[FlowMessage] = []
    for packet in await udp.packets(1.0):
        found += [p.flow for p in packet.payloads if isinstance(p, FlowPayload)]
        if len(found) >= count:
            break
    return found


Scenario = Callable[[ReferenceServer], Awaitable[object]]


@dataclass(frozen=True)
class Check:
    scenario: Scenario
    #: What the scenario observes of a clean server, and of one with the fault.
    clean: object
    faulty: object
    settings: dict[str, Any] = field(default_factory=dict)


async def bare_lf(server: ReferenceServer) -> object:
    raw = await Raw.open(server)
    await raw.send(b"CONNECT / RCTP/2.0\r\nCSeq: 1\r\n\r\n")
    head = await raw_head(raw)
    raw.close()
    return b"\r\n" in head and b"\n" not in head.replace(b"\r\n", b"")


async def no_cseq_echo(server: ReferenceServer) -> object:
    raw = await Raw.open(server)
    await raw.send(b"CONNECT / RCTP/2.0\r\nCSeq: 1\r\n\r\n")
    answered = await raw.response()
    raw.close()
    return answered.headers.get("CSeq")


async def status_of(server: ReferenceServer, method: str, target: str) -> object:
    session = await RawSession.open(server)
    answered = await ask(session, method, target)
    session.close()
    return answered.status


async def raw_status(server: ReferenceServer, request: bytes) -> object:
    raw = await Raw.open(server)
    await raw.send(request)
    answered = await raw.response()
    raw.close()
    return answered.status


async def no_allow(server: ReferenceServer) -> object:
    session = await RawSession.open(server)
    answered = await ask(session, "READ", WHEELS)
    session.close()
    return answered.status, answered.headers.get("Allow")


async def timeout_bye(server: ReferenceServer) -> object:
    session = await RawSession.open(server)
    found = await requests(session, 2.5)  # the session's timeout is 1 s
    session.close()
    return [(r.method, r.headers.get("Reason")) for r in found]


async def content_type(server: ReferenceServer) -> object:
    session = await RawSession.open(server)
    answered = await ask(session, "READ", "/head/control/tilt")
    session.close()
    return answered.headers.get("Content-Type")


async def mixed_case_write(server: ReferenceServer) -> object:
    session = await RawSession.open(server)
    assert (await ask(session, "ACQUIRE", "/head")).status == 200
    typed = [("Content-Type", "Application/RCTP-Values")]
    written = await ask(session, "WRITE", "/head/control/tilt", typed, b"\x00\x07")
    session.close()
    return written.status


async def bad_framing(server: ReferenceServer) -> object:
    raw = await Raw.open(server)
    await raw.send(b"CONNECT / RCTP/2.0\r\nCSeq: 1\r\nno colon here\r\n\r\n")
    answered = await raw.response()
    closed = await raw.closed(timeout=1.0)
    raw.close()
    return answered.status, closed


async def refresh(server: ReferenceServer) -> object:
    return await status_of(server, "CONNECT", "/")


async def partial_write(server: ReferenceServer) -> object:
    session = await RawSession.open(server)
    assert (await ask(session, "ACQUIRE", "/drive")).status == 200
    headers, body = settings_body(server, enabled=True, label="half", mode=9)
    written = await ask(session, "WRITE", SETTINGS, headers, body)
    read = await ask(session, "READ", SETTINGS, [("Nodes", "enabled, label")])
    session.close()
    codec = server.robot.codec(SETTINGS, nodes(SETTINGS, "enabled", "label"))
    values = codec.decode(read.body)
    return written.status, values["enabled"], values["label"]


async def watching(server: ReferenceServer) -> RawSession:
    session = await RawSession.open(server)
    assert (await ask(session, "SETUP", SETTINGS)).status == 200
    assert (await ask(session, "GO", SETTINGS)).status == 200
    return session


async def change_push(server: ReferenceServer) -> object:
    watcher = await watching(server)
    writer = await RawSession.open(server)
    assert (await ask(writer, "ACQUIRE", "/drive")).status == 200
    assert (await ask(writer, "WRITE", SETTINGS, *settings_body(server, mode=2))).status == 200
    found = await requests(watcher, 1.0)
    watcher.close()
    writer.close()
    return [r.method for r in found]


async def own_writes(server: ReferenceServer) -> object:
    session = await watching(server)
    assert (await ask(session, "ACQUIRE", "/drive")).status == 200
    await session.send("WRITE", SETTINGS, *settings_body(server, mode=2))
    answered, before = await answer(session)
    after = await requests(session, 0.5)
    session.close()
    return answered.status, [r.method for r in before + after]


async def unanswered_pushes(server: ReferenceServer) -> object:
    watcher = await watching(server)
    writer = await RawSession.open(server)
    assert (await ask(writer, "ACQUIRE", "/drive")).status == 200
    for step in range(7):
        headers, body = settings_body(server, mode=1 + step % 2)
        assert (await ask(writer, "WRITE", SETTINGS, headers, body)).status == 200
    found = await requests(watcher, 0.5)  # never answered
    watcher.close()
    writer.close()
    return len(found)


async def acquire_twice(server: ReferenceServer) -> object:
    first, second = await RawSession.open(server), await RawSession.open(server)
    assert (await ask(first, "ACQUIRE", "/drive")).status == 200
    again = await ask(second, "ACQUIRE", "/drive/settings")
    first.close()
    second.close()
    return again.status


async def write_unacquired(server: ReferenceServer) -> object:
    session = await RawSession.open(server)
    answered = await ask(session, "WRITE", SETTINGS, *settings_body(server, mode=1))
    session.close()
    return answered.status


async def release_while_writing(server: ReferenceServer) -> object:
    session, udp = await RawSession.open(server), Udp()
    assert (await ask(session, "ACQUIRE", "/drive")).status == 200
    await setup(session, udp, WHEELS, "write")
    answered = await ask(session, "RELEASE", "/drive")
    session.close()
    udp.close()
    return answered.status


async def privileges_after_the_session(server: ReferenceServer) -> object:
    first = await RawSession.open(server)
    assert (await ask(first, "ACQUIRE", "/drive")).status == 200
    first.close()
    await asyncio.sleep(0.3)
    second = await RawSession.open(server)
    answered = await ask(second, "ACQUIRE", "/drive")
    second.close()
    return answered.status


async def stream_timeout(server: ReferenceServer) -> object:
    session, udp = await RawSession.open(server), Udp()
    assert (await ask(session, "ACQUIRE", "/drive")).status == 200
    await setup(session, udp, WHEELS, "write")
    assert (await ask(session, "GO", WHEELS)).status == 200
    found = await requests(session, 1.8)  # nothing written: the 1 s writeTimeout passes
    session.close()
    udp.close()
    return [(r.method, r.headers.get("Reason")) for r in found]


async def paused(server: ReferenceServer) -> object:
    session, udp = await RawSession.open(server), Udp()
    await setup(session, udp, RANGE, "read")
    assert (await ask(session, "GO", RANGE)).status == 200
    assert await udp.recv() is not None
    assert (await ask(session, "PAUSE", RANGE)).status == 200
    await udp.packets(0.15)  # what was on its way
    later = await udp.packets(0.3)
    session.close()
    udp.close()
    return bool(later)


async def first_port(server: ReferenceServer) -> object:
    session, first, second = await RawSession.open(server), Udp(), Udp()
    await setup(session, first, RANGE, "read")
    await setup(session, second, RANGE, "read")
    assert (await ask(session, "GO", RANGE)).status == 200
    got = (await first.recv(0.4) is not None, await second.recv(0.4) is not None)
    session.close()
    first.close()
    second.close()
    return got


async def stale_data(server: ReferenceServer) -> object:
    applied: list[object] = []
    command = server.robot.command

    def recorded(by: Any, values: Any, now: float) -> None:
        applied.append(values.get(f"{WHEELS}/left"))
        command(by, values, now)

    server.robot.command = recorded  # type: ignore[method-assign]
    session, udp = await RawSession.open(server), Udp()
    assert (await ask(session, "ACQUIRE", "/drive")).status == 200
    tag, stream = await setup(session, udp, WHEELS, "write")
    assert (await ask(session, "GO", WHEELS)).status == 200
    node = server.model.node(WHEELS)
    assert isinstance(node, AccessNode)
    codec = stream_codec(node, Direction.WRITE)
    for sequence, left in ((100, 0.5), (90, -0.5)):  # the second is late
        body = codec.encode({"left": left, "right": left})
        udp.send(server, tag, [(PayloadType.DATA, body, stream)], sequence)
        await asyncio.sleep(0.1)
    session.close()
    udp.close()
    return applied


async def sequence_steps(server: ReferenceServer) -> object:
    session, udp = await RawSession.open(server), Udp()
    await setup(session, udp, RANGE, "read")
    assert (await ask(session, "GO", RANGE)).status == 200
    first, second = (await udp.packets(0.15))[:2]
    session.close()
    udp.close()
    return (second.sequence - first.sequence) % 65536


async def heartbeat(server: ReferenceServer) -> object:
    session, udp = await RawSession.open(server), Udp()
    tag, _ = await setup(session, udp, RANGE, "read")
    udp.send(server, tag, [(PayloadType.FLOW, encode_flow(HeartbeatRequest(1, 123456789)), 0)])
    (ack,) = await flow_answers(udp, 1)
    session.close()
    udp.close()
    return isinstance(ack, HeartbeatAck) and ack.t1 == 123456789


async def short_interval(server: ReferenceServer) -> object:
    session, udp = await RawSession.open(server), Udp()
    tag, stream = await setup(session, udp, RANGE, "read")
    request = IntervalSet(1, Direction.READ, 1000)  # the RCML says 50 ms
    udp.send(server, tag, [(PayloadType.FLOW, encode_flow(request), stream)])
    (reply,) = await flow_answers(udp, 1)
    session.close()
    udp.close()
    return type(reply).__name__


async def unknown_payload(server: ReferenceServer) -> object:
    session, udp = await RawSession.open(server), Udp()
    tag, _ = await setup(session, udp, RANGE, "read")
    beat = encode_flow(HeartbeatRequest(1, 1))
    udp.send(server, tag, [(9, b"skip me", 0), (PayloadType.FLOW, beat, 0)])
    answered = await flow_answers(udp, 1)
    session.close()
    udp.close()
    return len(answered)


async def repeated_flow(server: ReferenceServer) -> object:
    session, udp = await RawSession.open(server), Udp()
    tag, _ = await setup(session, udp, RANGE, "read")
    beat = encode_flow(HeartbeatRequest(7, 99))
    udp.send(server, tag, [(PayloadType.FLOW, beat, 0)])
    await asyncio.sleep(0.05)
    udp.send(server, tag, [(PayloadType.FLOW, beat, 0)])  # sent again: the same id
    first, second = await flow_answers(udp, 2)
    session.close()
    udp.close()
    return first == second


VALUES = [("Content-Type", "application/rctp-values")]


async def write_settings(server: ReferenceServer, name: str, body: bytes) -> object:
    """The status of a WRITE of one node of /drive/settings, and the node's value read after."""
    session = await RawSession.open(server)
    assert (await ask(session, "ACQUIRE", "/drive")).status == 200
    written = await ask(session, "WRITE", SETTINGS, [("Nodes", name), *VALUES], body)
    read = await ask(session, "READ", SETTINGS, [("Nodes", name)])
    session.close()
    return written.status, server.robot.codec(SETTINGS, nodes(SETTINGS, name)).decode(read.body)


async def settings_read_whole(server: ReferenceServer) -> object:
    """The body of a READ of /drive/settings, after each node was written alone."""
    session = await RawSession.open(server)
    assert (await ask(session, "ACQUIRE", "/drive")).status == 200
    for name, body in (("enabled", b"\x01"), ("label", b"\x00\x01x"), ("mode", b"\x02")):
        assert (
            await ask(session, "WRITE", SETTINGS, [("Nodes", name), *VALUES], body)
        ).status == 200
    read = await ask(session, "READ", SETTINGS)
    session.close()
    return read.body


async def write_nan(server: ReferenceServer) -> object:
    session = await RawSession.open(server)
    assert (await ask(session, "ACQUIRE", "/head")).status == 200
    nan = bytes.fromhex("7ff8000000000000")  # a float64 NaN; /head/control/volume is 0 to 1
    written = await ask(session, "WRITE", "/head/control/volume", VALUES, nan)
    session.close()
    return written.status


def _status_check(method: str, target: str, clean: int, faulty: int) -> Check:
    return Check(lambda server: status_of(server, method, target), clean, faulty)


SERVER_CHECKS: dict[Fault, Check] = {
    Fault.BARE_LF: Check(bare_lf, True, False),
    Fault.NO_CSEQ_ECHO: Check(no_cseq_echo, "1", None),
    Fault.WRONG_STATUS: _status_check("READ", "/nowhere", 404, 400),
    Fault.UNKNOWN_METHOD_400: _status_check("FROBNICATE", "/", 501, 400),
    Fault.VERSION_IGNORED: Check(
        lambda s: raw_status(s, b"CONNECT / RCTP/1.0\r\nCSeq: 1\r\n\r\n"), 505, 200
    ),
    Fault.SESSION_UNCHECKED: Check(
        lambda s: raw_status(s, b"READ /head/control/tilt RCTP/2.0\r\nCSeq: 1\r\n\r\n"), 454, 200
    ),
    Fault.NO_ALLOW: Check(no_allow, (405, "ACQUIRE, RELEASE, SETUP, GO, PAUSE, STOP"), (405, None)),
    Fault.NO_TIMEOUT_BYE: Check(
        timeout_bye, [("BYE", "timeout")], [], settings={"session_timeout": 1}
    ),
    Fault.NO_CONTENT_TYPE: Check(content_type, "application/rctp-values", None),
    Fault.OPEN_AFTER_BAD_FRAMING: Check(bad_framing, (400, True), (400, False)),
    Fault.REFRESH_REFUSED: Check(refresh, 200, 455),
    Fault.PERMISSION_IGNORED: _status_check("READ", "/head/control/lcd", 403, 200),
    Fault.CASE_SENSITIVE_TOKENS: Check(mixed_case_write, 200, 415),
    Fault.PARTIAL_WRITE: Check(partial_write, (422, False, "label"), (422, True, "half")),
    Fault.NO_CHANGE_PUSH: Check(change_push, ["WRITE"], []),
    Fault.ECHO_OWN_WRITES: Check(own_writes, (200, []), (200, ["WRITE"])),
    Fault.UNBOUNDED_PUSHES: Check(unanswered_pushes, 4, 7),
    Fault.ACQUIRE_NOT_EXCLUSIVE: Check(acquire_twice, 471, 200),
    Fault.WRITE_WITHOUT_ACQUIRE: Check(write_unacquired, 470, 200),
    Fault.RELEASE_UNHELD: _status_check("RELEASE", "/drive", 470, 200),
    Fault.RELEASE_WHILE_WRITING: Check(release_while_writing, 455, 200),
    Fault.PRIVILEGES_KEPT: Check(privileges_after_the_session, 200, 471),
    Fault.NO_TIMEOUT_STOP: Check(stream_timeout, [("STOP", "timeout")], []),
    Fault.PAUSE_IGNORED: Check(paused, False, True),
    Fault.FIRST_CLIENT_PORT: Check(first_port, (False, True), (True, False)),
    Fault.STALE_DATA_APPLIED: Check(stale_data, [0.5], [0.5, -0.5]),
    Fault.SEQUENCE_SKIPS: Check(sequence_steps, 1, 2),
    Fault.HEARTBEAT_NO_T1: Check(heartbeat, True, False),
    Fault.SHORT_INTERVAL_ACCEPTED: Check(short_interval, "Nack", "IntervalSetAck"),
    Fault.UNKNOWN_PAYLOAD_DROPS: Check(unknown_payload, 1, 0),
    Fault.FLOW_ANSWERS_FORGOTTEN: Check(repeated_flow, True, False),
    Fault.BOOL_NONZERO_TRUE: Check(
        lambda s: write_settings(s, "enabled", b"\x02"),
        (422, {"enabled": False}),
        (200, {"enabled": True}),
    ),
    Fault.STRING_SIZE_UNCHECKED: Check(
        lambda s: write_settings(s, "label", b"\x00\x21" + b"a" * 33),
        (422, {"label": "label"}),
        (200, {"label": "a" * 33}),
    ),
    Fault.DOCUMENT_ORDER_VALUES: Check(
        settings_read_whole, b"\x01\x00\x01x\x02", b"\x02\x01\x00\x01x"
    ),
    Fault.NAN_IN_RANGE: Check(write_nan, 422, 200),
}


def test_every_server_fault_has_a_scenario() -> None:
    assert set(SERVER_CHECKS) == SERVER_FAULTS


@pytest.mark.parametrize(
    "fault", sorted(SERVER_FAULTS, key=lambda f: f.value), ids=lambda f: f.value
)
def test_each_server_fault_changes_what_the_server_does(fault: Fault) -> None:
    check = SERVER_CHECKS[fault]

    async def observe(faults: frozenset[Fault]) -> object:
        async with serving(TESTBOT, faults=faults, **check.settings) as server:
            return await check.scenario(server)

    async def main() -> tuple[object, object]:
        return await observe(frozenset()), await observe(frozenset({fault}))

    clean, faulty = asyncio.run(asyncio.wait_for(main(), TEST_BOUND))
    assert clean == check.clean, f"the clean server: {clean!r}"
    assert faulty == check.faulty, f"with {fault.value}: {faulty!r}"


def test_the_data_stream_faults_make_a_faulty_endpoint_and_only_they() -> None:
    async def main() -> list[type[Endpoint]]:
        made = []
        for faults in (frozenset(), frozenset({Fault.PAUSE_IGNORED}), STREAM_FAULTS):
            async with serving(TESTBOT, faults=faults) as server:
                session, udp = await RawSession.open(server), Udp()
                await setup(session, udp, RANGE, "read")
                (control,) = server.controls.values()
                assert control.session is not None
                made.append(type(control.session.endpoint))
                session.close()
                udp.close()
        return made  # type: ignore[return-value]

    made = asyncio.run(asyncio.wait_for(main(), TEST_BOUND))
    assert made == [Endpoint, Endpoint, FaultyEndpoint]


# -- the RSP robot: a scenario per fault, sans I/O -------------------------------------------------

CUBO = robot_model()
LOCAL = ("127.0.0.1", 40000)
OTHER = ("127.0.0.1", 40001)
T = CUBO.period


def position(name: str) -> int:
    found = CUBO.device(name)
    assert found is not None, name
    return found.position


MOTION = {"duration": 1000, "leftArm": 0, "rightArm": 0, "headTilt": 0}


class Local:
    """A local system made by hand: packets as a case would build them, the robot's read back."""

    def __init__(self, faults: frozenset[Fault] = frozenset()) -> None:
        self.robot = FaultyRobotEndpoint(faults, CUBO) if faults else RobotEndpoint(CUBO)
        self.wire = SessionWire(self.robot.codec, Encryption.NONE, RspDirection.DOWNLINK)
        self.now = 0.0
        #: What the robot sent, in order.
        self.received: list[RspPacket] = []
        self.raw: list[bytes] = []

    def send(self, data: bytes, source: tuple[str, int] = LOCAL) -> None:
        self.robot.receive_datagram(data, source, self.now)
        self._collect()

    def _collect(self) -> None:
        for data, _ in self.robot.datagrams_to_send(self.now):
            self.raw.append(data)
            header = pull_header(data)
            if header.model_id == CUBO.model_id:
                self.received.append(self.robot.codec.pull_packet(data))

    def hello(self, nonce: bytes = b"n" * 16) -> bytes:
        data = self.wire.build(PacketType.HELLO, Hello(nonce, round(T * 1000)), self.now)
        self.send(data)
        return data

    def open(self) -> Local:
        self.hello()
        (welcome,) = self.of(PacketType.WELCOME)
        self.wire.session_id = welcome.header.session_id
        return self

    def downlink(self, *items: Item, buffer: int = 0, source: tuple[str, int] = LOCAL) -> bytes:
        data = self.wire.build(PacketType.DOWNLINK, MapBody(items), self.now, buffer)
        self.send(data, source)
        return data

    def run(self, seconds: float) -> None:
        end = self.now + seconds
        while self.now < end:
            self.now = min(end, self.now + T / 4)
            self.robot.handle_timer(self.now)
            self._collect()

    def of(self, kind: PacketType) -> list[RspPacket]:
        return [p for p in self.received if p.header.type is kind]

    def acks(self) -> list[tuple[int, int | None]]:
        found = []
        for packet in self.of(PacketType.ACK):
            assert isinstance(packet.body, MapBody)
            found += [(item.device, item.id) for item in packet.body.items]
        return found

    def reported(self) -> set[str]:
        """The devices the UPLINKs carried."""
        found = set()
        for packet in self.of(PacketType.UPLINK):
            assert isinstance(packet.body, MapBody)
            found |= {CUBO.devices[item.device].name for item in packet.body.items}
        return found


FIRE = position("irFire")


def fire(ident: int) -> Item:
    return Item(FIRE, ident, {"code": 7})


def motion(ident: int) -> Item:
    return Item(position("motion"), ident, MOTION)


def no_retransmission(local: Local) -> object:
    local.hello()
    local.hello()  # its WELCOME lost: the same nonce again
    welcomes = len(local.of(PacketType.WELCOME))
    local.wire.session_id = local.of(PacketType.WELCOME)[0].header.session_id
    local.downlink(Item(position("lowBattery")))
    assert local.robot.occur("lowBattery", {"charge": 9}) is not None
    local.run(4 * INITIAL_RTO_PERIODS * T)  # never acknowledged
    sends = 0
    for packet in local.of(PacketType.UPLINK):
        assert isinstance(packet.body, MapBody)
        sends += sum(1 for item in packet.body.items if item.device == position("lowBattery"))
    return welcomes, sends > 1


def ack_id(local: Local) -> object:
    local.downlink(fire(5))
    return local.acks()


def repeated(local: Local) -> object:
    local.downlink(fire(0))
    local.downlink(fire(0))  # its ACK lost: carried again (R-RSP-27)
    taken = [e for e in _events(local) if type(e).__name__ == "OccurrenceReceived"]
    return len(local.acks()), len(taken)


def _events(local: Local) -> list[object]:
    found = []
    while (event := local.robot.next_event()) is not None:
        found.append(event)
    return found


def replayed(local: Local) -> object:
    data = local.downlink(fire(0))
    local.send(data)  # the same datagram again: seen before
    wheel = position("leftWheel")
    local.downlink(Item(position("base")), Item(wheel, None, {"speed": 100}))
    late = local.wire.build(
        PacketType.DOWNLINK,
        MapBody((Item(position("base")), Item(wheel, None, {"speed": 50}))),
        local.now,
    )
    local.downlink(Item(position("base")))  # newer than `late`
    local.send(late)
    local.run(2 * T)
    return len(local.acks()), local.robot.effectors(local.now)["leftWheel"]["speed"]


def spoofed_session(local: Local) -> object:
    data = bytearray(local.wire.build(PacketType.DOWNLINK, MapBody((fire(0),)), local.now))
    data[16] ^= 1  # another session's ID
    local.send(bytes(data))
    return len(local.acks())


def other_source(local: Local) -> object:
    local.downlink(fire(0), source=OTHER)
    return len(local.acks())


def refused_model(local: Local) -> object:
    header = Header(1, CUBO.model_id + 1, Encryption.NONE, PacketType.HELLO, 0, 0, 0, 0, 0)
    hello = push_header(header) + push_session_body(header, Hello(b"x" * 16, 20))
    local.send(hello, OTHER)
    (refused,) = local.raw[-1:]
    return pull_header(refused).model_id


def free_buffers(local: Local) -> object:
    for ident in range(CUBO.command_buffers + 2):
        local.downlink(motion(ident))
    buffers = [p.header.buffer for p in local.of(PacketType.ACK)]
    return len(buffers), buffers[0], buffers[-1]


def requested(local: Local) -> object:
    local.downlink(Item(position("battery")))
    local.robot.set_state("battery", {"charge": 80})
    local.robot.set_state("temperature", {"temperature": 200})
    local.run(3 * T)
    return local.reported()


def sequences(local: Local) -> object:
    local.run(12 * T)  # UPLINKs, empty, every 5 periods
    numbers = [p.header.sequence for p in local.received]
    return len(set(numbers)) == len(numbers)


def clear_buffer(local: Local) -> object:
    local.downlink(motion(0))
    local.downlink(motion(1))
    local.downlink(buffer=CLEAR_BUFFER)
    return local.robot.free_buffers


def silent_peer(local: Local) -> object:
    local.run(10.5)
    byes = [p.body for p in local.of(PacketType.BYE)]
    return byes, local.robot.session is None


def link_lost(local: Local) -> object:
    base, wheel = position("base"), position("leftWheel")
    local.downlink(Item(base), Item(wheel, None, {"speed": 100}))
    local.run(2 * T)
    moving = local.robot.effectors(local.now)["leftWheel"]["speed"]
    local.run(30 * T)  # silence: the link is lost after 25 periods
    return moving, local.robot.effectors(local.now)["leftWheel"]["speed"]


def long_image(local: Local) -> object:
    """A DOWNLINK whose LCD image is a byte longer than its size, with a command."""
    lcd = CUBO.device("lcd")
    assert lcd is not None
    size = lcd.fields[0].type.size
    data = local.wire.build(
        PacketType.DOWNLINK,
        MapBody((Item(lcd.position, None, {"image": b"a" * size}), fire(3))),
        local.now,
    )
    local.send(
        data.replace(size.to_bytes(2) + b"a" * size, (size + 1).to_bytes(2) + b"a" * (size + 1))
    )
    return local.acks()


@dataclass(frozen=True)
class RobotCheck:
    scenario: Callable[[Local], object]
    clean: object
    faulty: object
    #: The scenario opens the session itself.
    opens: bool = False


def _bye(reason: ByeReason) -> Any:
    from rcmlconf.rsp.codec import Bye

    return Bye(reason)


ROBOT_CHECKS: dict[Fault, RobotCheck] = {
    Fault.NO_RETRANSMISSION: RobotCheck(no_retransmission, (2, True), (1, False), opens=True),
    Fault.ACK_NEXT_ID: RobotCheck(ack_id, [(FIRE, 5)], [(FIRE, 6)]),
    Fault.REPEAT_NOT_ACKED: RobotCheck(repeated, (2, 1), (1, 1)),
    Fault.DUPLICATES_TAKEN: RobotCheck(repeated, (2, 1), (2, 2)),
    Fault.REPLAY_WINDOW_OFF: RobotCheck(replayed, (1, 100), (2, 50)),
    Fault.SESSION_ID_UNCHECKED: RobotCheck(spoofed_session, 0, 1),
    Fault.SOURCE_UNCHECKED: RobotCheck(other_source, 0, 1),
    Fault.REFUSED_OWN_MODEL: RobotCheck(refused_model, CUBO.model_id + 1, CUBO.model_id),
    Fault.FREE_BUFFERS_STUCK: RobotCheck(
        free_buffers,
        (CUBO.command_buffers, CUBO.command_buffers - 1, 0),
        (CUBO.command_buffers + 2, CUBO.command_buffers, CUBO.command_buffers),
    ),
    Fault.UNREQUESTED_REPORTED: RobotCheck(requested, {"battery"}, {"battery", "temperature"}),
    Fault.SEQUENCE_FROZEN: RobotCheck(sequences, True, False),
    Fault.CLEAR_BUFFER_IGNORED: RobotCheck(
        clear_buffer, CUBO.command_buffers, CUBO.command_buffers - 2
    ),
    Fault.SILENT_TIMEOUT: RobotCheck(silent_peer, ([_bye(ByeReason.TIMEOUT)], True), ([], True)),
    Fault.NO_STOP_ON_LOSS: RobotCheck(link_lost, (100, 0), (100, 100)),
    Fault.PAYLOAD_SIZE_UNCHECKED: RobotCheck(long_image, [], [(FIRE, 3)]),
}


def test_every_robot_fault_has_a_scenario() -> None:
    assert set(ROBOT_CHECKS) == ROBOT_FAULTS


@pytest.mark.parametrize(
    "fault", sorted(ROBOT_FAULTS, key=lambda f: f.value), ids=lambda f: f.value
)
def test_each_robot_fault_changes_what_the_robot_does(fault: Fault) -> None:
    check = ROBOT_CHECKS[fault]

    def observe(faults: frozenset[Fault]) -> object:
        local = Local(faults)
        return check.scenario(local if check.opens else local.open())

    assert observe(frozenset()) == check.clean, "the clean robot"
    assert observe(frozenset({fault})) == check.faulty, f"with {fault.value}"


def test_a_faulty_robot_says_so_at_start(caplog: pytest.LogCaptureFixture) -> None:
    async def main() -> None:
        robot = ReferenceRobot(CUBO, RobotSettings(port=0, faults=frozenset({Fault.ACK_NEXT_ID})))
        await robot.start()
        assert isinstance(robot.endpoint, FaultyRobotEndpoint)
        assert robot.endpoint.faults == {Fault.ACK_NEXT_ID}
        robot.stop()

    asyncio.run(asyncio.wait_for(main(), TEST_BOUND))
    assert any("ack-next-id" in r.getMessage() for r in caplog.records if r.levelname == "WARNING")
