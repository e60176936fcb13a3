"""rctp/msg: the server's own requests and the answers it takes to them — how it numbers them,
and that an answer it cannot frame, or that answers none of them, closes the connection
(specs/rctp-2.0.md D-RCTP-6, D-RCTP-10, D-RCTP-27, R-RCTP-4, R-RCTP-12, R-RCTP-19).

The server's requests are data-change WRITEs (D-RCTP-27): one session (the watcher) plays an
event access, another (the writer) changes one of its nodes. Holding the privilege, the cases
that make them run alone (`serial`), and write back the value they found."""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import AsyncIterator, Callable
from dataclasses import dataclass

from rcmlconf.conformance.cases.rctp_msg.grammar import expect_cseq, holding
from rcmlconf.conformance.context import Context
from rcmlconf.conformance.picks import RW
from rcmlconf.conformance.probes.control import ControlProbe, describe
from rcmlconf.conformance.registry import case
from rcmlconf.conformance.verdicts import Inconclusive, NotApplicable
from rcmlconf.errors import ProtocolError
from rcmlconf.rcml.model import AccessNode, AccessType, DataNode
from rcmlconf.rctp.bodies import ValuesCodec
from rcmlconf.rctp.fields import format_nodes
from rcmlconf.rctp.messages import VERSION, Request
from rcmlconf.rctp.targets import format_target
from rcmlconf.values import Value
from rcmlconf.values.types import Kind

#: An answer of the case's to a request of the server's: its bytes, from the request's CSeq and
#: the session.
Answer = Callable[[str, str], bytes]
#: Answers to a data-change WRITE that cannot be framed (D-RCTP-4, §2.1), by what is wrong.
UNFRAMEABLE: dict[str, Answer] = {
    "with bare LF line endings": lambda cseq, session: (
        f"{VERSION} 200 OK\nCSeq: {cseq}\nSession: {session}\n\n".encode()
    ),
    "with the status code 2x0": lambda cseq, session: (
        f"{VERSION} 2x0 OK\r\nCSeq: {cseq}\r\nSession: {session}\r\n\r\n".encode()
    ),
}


@case(
    "rctp/msg/response-without-request",
    "A response when the server waits for none, or a broken status line, gets no answer and the "
    "connection is closed",
    ["R-RCTP-12"],
)
async def response_without_request(ctx: Context) -> None:
    for data in (b"RCTP/2.0 200 OK\r\nCSeq: 1\r\n\r\n", b"RCTP/2.0 2x0 OK\r\nCSeq: 1\r\n\r\n"):
        probe = await ctx.session()
        await probe.send(data)
        outcome = await probe.outcome(ctx.wait)
        ctx.expect(outcome == "closed", "the connection closed without an answer", outcome)


@case(
    "rctp/msg/server-requests-numbered",
    "The server numbers its own requests 1, 2, 3, ... whatever the client's CSeq, and names the "
    "session in each",
    ["R-RCTP-4", "R-RCTP-19"],
    serial=True,
)
async def server_requests_numbered(ctx: Context) -> None:
    async with pushes(ctx) as made:
        for number, value in enumerate((made.other, made.original) * 2, start=1):
            found = await made.pushed(value)
            expect_cseq(ctx, found, number, "R-RCTP-4")
            given = found.headers.get("Session")
            session = made.watcher.session
            ctx.expect(given == session, f"Session: {session}", f"Session: {given}", "R-RCTP-19")
            await made.watcher.answer(found)


@case(
    "rctp/msg/response-wrong-cseq",
    "An answer to the server's request with another CSeq than that request's makes the server "
    "close the connection, answering nothing",
    ["R-RCTP-12"],
    serial=True,
)
async def response_wrong_cseq(ctx: Context) -> None:
    def another(cseq: str, session: str) -> bytes:
        wrong = int(cseq or 0) + 1
        return f"{VERSION} 200 OK\r\nCSeq: {wrong}\r\nSession: {session}\r\n\r\n".encode()

    await _closes_on(ctx, another, "with the CSeq of no request")


@case(
    "rctp/msg/response-unframeable",
    "An answer to the server's data-change WRITE that cannot be framed (bare LF line endings, a"
    " status code 2x0) makes the server close the connection, answering nothing",
    ["R-RCTP-12"],
    serial=True,
)
async def response_unframeable(ctx: Context) -> None:
    # response-without-request sends such answers when the server waits for none, which a
    # server closes for that reason alone; one that takes a loosely framed answer to its own
    # request (a reader that splits lines on LF) passes it, and not this.
    for what, answer in UNFRAMEABLE.items():
        await _closes_on(ctx, answer, what)


async def _closes_on(ctx: Context, answer: Answer, what: str) -> None:
    """A data-change WRITE answered by `answer` (`what` says how): the server closes the
    connection, answering nothing (R-RCTP-12)."""
    async with pushes(ctx) as made:
        found = await made.pushed(made.other)
        session = made.watcher.session or ""
        await made.watcher.send(answer(found.headers.get("CSeq") or "", session))
        outcome = await made.watcher.outcome(ctx.wait)
        ctx.expect(
            outcome == "closed",
            f"the connection closed without an answer, on the answer {what}",
            outcome,
        )


# -- helpers ---------------------------------------------------------------------------------


@dataclass
class Pushes:
    """One session playing an event access (the watcher), another changing one of its nodes
    (the writer), so that the server sends the watcher data-change WRITEs (D-RCTP-27)."""

    watcher: ControlProbe
    writer: ControlProbe
    access: AccessNode
    node: DataNode
    codec: ValuesCodec[DataNode]
    original: Value
    other: Value

    async def write(self, value: Value) -> None:
        nodes = [("Nodes", format_nodes([self.node.name]))]
        body = self.codec.encode({self.node.name: value})
        answer = await self.writer.request("WRITE", format_target(self.access.path), nodes, body)
        if answer.status != 200:
            raise Inconclusive(f"WRITE {self.node.path} was answered {answer.status}")

    async def pushed(self, value: Value) -> Request:
        """The data-change WRITE the watcher gets once the writer wrote `value`, unanswered."""
        await self.write(value)
        found = await self.watcher.message()
        if not isinstance(found, Request) or found.method != "WRITE":
            raise Inconclusive(f"no data-change WRITE after a change: {describe(found)}")
        return found


@contextlib.asynccontextmanager
async def pushes(ctx: Context) -> AsyncIterator[Pushes]:
    """The watcher and the writer; the node's value is put back and the privilege released."""
    access, node = _changeable(ctx)
    path = format_target(access.path)
    watcher = await ctx.session()
    for method in ("SETUP", "GO"):
        answer = await watcher.request(method, path)
        if answer.status != 200:
            raise Inconclusive(f"{method} {access.path} was answered {answer.status}")
    writer = await ctx.session()
    codec = ValuesCodec([node], access.path, "R-RCTP-28")
    async with holding(ctx, writer, access.path):
        read = await writer.request("READ", path, [("Nodes", format_nodes([node.name]))])
        if read.status != 200:
            raise Inconclusive(f"READ {node.path} was answered {read.status}")
        try:
            original = codec.decode(read.body)[node.name]
        except ProtocolError as error:
            reason = f"READ {node.path} answered a body that does not decode: {error}"
            raise Inconclusive(reason) from None
        pushes = Pushes(watcher, writer, access, node, codec, original, _other(node, original))
        try:
            yield pushes
        finally:
            with contextlib.suppress(Exception):
                await asyncio.wait_for(pushes.write(original), ctx.wait)


def _changeable(ctx: Context) -> tuple[AccessNode, DataNode]:
    """A readable, writable, one-value node of an event access, of a type `_other` can change."""
    for access in ctx.robot.access_nodes():
        if access.type is not AccessType.EVENT:
            continue
        for node in access.data:
            kind = node.type.base.kind
            ranged = kind in (Kind.INTEGER, Kind.FLOAT) and None not in (node.minimum, node.maximum)
            if RW in node.permission and node.type.count == 1 and (kind is Kind.BOOL or ranged):
                return access, node
    raise NotApplicable("the robot has no event access with a writable bool or ranged number")


def _other(node: DataNode, value: Value) -> Value:
    """A valid value of `node` other than `value`."""
    if node.type.base.kind is Kind.BOOL:
        return not value
    # `_changeable` chose a node with both
    assert node.minimum is not None
    assert node.maximum is not None
    chosen = node.minimum if value != node.minimum else node.maximum
    return float(chosen) if node.type.base.kind is Kind.FLOAT else int(chosen)
