"""rctp/event: data-change events — the server's WRITE of an event access that plays
(specs/rctp-2.0.md §3 D-RCTP-14, §5 D-RCTP-17, D-RCTP-27, R-RCTP-4, R-RCTP-25, R-RCTP-32,
R-RCTP-54, R-RCTP-55).

A watching session SETs UP and GOes an event access; a second session ACQUIREs it and WRITEs a
readable and writable node of it, and the server must push the change to the watcher. Changes the
robot makes by itself come at its own pace, so the cases make their own (and tolerate the
robot's: a WRITE that does not list the node written is checked, answered and passed over).
Holding the privilege, they run alone (`serial`), and write back the values they found. Where a
case must see that no WRITE comes, it waits `_SETTLE` (scaled) after the change: D-RCTP-27's
bound on a push, so that a server that looks for changes at any pace the spec allows can neither
pass wrongly nor fail wrongly.
"""

from __future__ import annotations

import asyncio

from rcmlconf.conformance.context import Context
from rcmlconf.conformance.picks import RW, Named
from rcmlconf.conformance.probes.control import ControlProbe
from rcmlconf.conformance.probes.held import came_by, margin, never_came
from rcmlconf.conformance.probes.nodes import (
    acquire,
    check_values,
    other_values,
    put_back,
    read,
    sessions,
    values_for,
    write,
    writer,
)
from rcmlconf.conformance.registry import case
from rcmlconf.conformance.verdicts import Failed, Inconclusive, NotApplicable
from rcmlconf.errors import ValueTextError
from rcmlconf.rcml.model import AccessNode, AccessType, DataNode
from rcmlconf.rctp.fields import parse_nodes
from rcmlconf.rctp.messages import PUSH_DELAY, SERVER_METHODS, Message, Request, Response
from rcmlconf.rctp.targets import parse_target
from rcmlconf.values import Value
from rcmlconf.values.shown import values_text

#: Seconds without a WRITE that count as "none came" (scaled by --timeout-scale): D-RCTP-27's
#: bound, within which a change is pushed.
_SETTLE = PUSH_DELAY
#: Seconds between the changes of the case that floods a watcher, so that a server that looks
#: for changes every 10 ms (D-RCTP-27) sees each one.
_GAP = 0.015
#: Changes made while the watcher does not answer: twice R-RCTP-55's four.
_FLOOD = 8


def _shown(node: DataNode, value: Value | None) -> str:
    """`name=value` in the value's text form (D-RCML-14), or `name absent`."""
    return f"{node.name} absent" if value is None else values_text([node], {node.name: value})[0]


def _changing(ctx: Context, count: int = 1) -> Named:
    """A readable and writable node of an event access with `count` valid values besides any
    one. Accesses whose every readable node is writable come first: nothing in them changes by
    itself between the case's changes."""
    events = [a for a in ctx.robot.access_nodes() if a.type is AccessType.EVENT]
    events.sort(key=lambda a: not all(RW in n.permission for n in a.readable()))
    for access in events:
        for node in access.data:
            if RW in node.permission and len(values_for(node)) > count:
                return Named(access.path, (node,), event=True)
    raise NotApplicable(f"the robot has no rw node of an event access with {count + 1} values")


async def _within(probe: ControlProbe, wait: float) -> Message | None:
    """The next message within `wait`, or None; the connection must stay open."""
    try:
        message = await probe.message(wait)
    except Failed as failed:
        if failed.requirement == "R-RCTP-5" and (failed.actual or "").startswith("nothing"):
            return None
        raise
    if message is None:
        raise Failed("R-RCTP-32", "the connection kept open", "the server closed it")
    return message


class _Watcher:
    """A session where an event access plays, and every request the server sent it: each is
    checked as it comes (R-RCTP-25, its CSeq R-RCTP-4, its Session R-RCTP-19)."""

    def __init__(self, ctx: Context, probe: ControlProbe, named: Named) -> None:
        self.ctx, self.probe, self.named = ctx, probe, named
        self.seen: list[Request] = []

    @classmethod
    async def start(cls, ctx: Context, named: Named) -> _Watcher:
        """A new session with the access SET UP and GOing."""
        watcher = cls(ctx, await ctx.session(), named)
        for method in ("SETUP", "GO"):
            answer, _ = await watcher.ask(method)
            if answer.status != 200:
                raise Inconclusive(f"{method} {named.path} was answered {answer.status}")
        return watcher

    def _take(self, message: Message) -> Request:
        ctx = self.ctx
        if not isinstance(message, Request):
            raise Failed("R-RCTP-12", "a request of the server", f"a response {message.status}")
        if message.method not in SERVER_METHODS:
            raise Failed("R-RCTP-25", "WRITE, STOP or BYE", f"{message.method} {message.target}")
        self.seen.append(message)
        number, wanted = message.headers.get("CSeq"), len(self.seen)
        ctx.expect(number == str(wanted), f"CSeq: {wanted}", f"CSeq: {number}", "R-RCTP-4")
        session = message.headers.get("Session")
        ctx.expect(
            session == self.probe.session,
            f"Session: {self.probe.session}",
            f"Session: {session}",
            "R-RCTP-19",
        )
        return message

    async def next(self, wait: float) -> Request | None:
        """The server's next request within `wait`, unanswered, or None."""
        message = await _within(self.probe, wait)
        return None if message is None else self._take(message)

    def values(self, request: Request) -> dict[str, Value]:
        """The values of a data-change WRITE of the access: listed nodes of it (R-RCTP-30), the
        body exactly their values (R-RCTP-32)."""
        ctx, named = self.ctx, self.named
        access = ctx.robot.node(named.path)
        assert isinstance(access, AccessNode)
        what = f"WRITE {named.target}"
        shown = f"{request.method} {request.target}"
        ctx.expect(request.method == "WRITE", what, shown, "R-RCTP-32")
        ctx.expect(parse_target(request.target).path == access.path, what, shown, "R-RCTP-32")
        text = request.headers.get("Nodes")
        try:
            names = parse_nodes(text or "")
        except ValueTextError as error:
            raise Failed(
                "R-RCTP-30", "Nodes: readable nodes, canonical order", f"{error}"
            ) from None
        readable = {n.name: n for n in access.readable()}
        expected = f"Nodes among {', '.join(readable)}"
        ctx.expect(set(names) <= readable.keys(), expected, f"Nodes: {text}", "R-RCTP-30")
        return check_values(ctx, request, [readable[n] for n in names], access.path, "R-RCTP-32")

    async def push(self, status: int = 200, reason: str = "OK") -> dict[str, Value]:
        """The values of the server's next WRITE listing the node, answered `status`; the
        requests before it are checked and answered 200. It must come within D-RCTP-27's bound
        (scaled) of the change, or of the answer that made room for it: the caller's last."""
        ctx, loop = self.ctx, asyncio.get_running_loop()
        node, wait = self.named.node.name, PUSH_DELAY * ctx.scale
        since = loop.time()
        what = f"a WRITE of {self.named.path} within {wait:g} s"
        # A hold of the harness's loop excuses a WRITE read that much late, so the wait goes on a
        # margin past the bound: a server that never pushes fails however loaded the machine.
        while (left := since + wait + margin(ctx) - loop.time()) > 0:
            request = await self.next(left)
            if request is None:
                break
            arrived = loop.time()
            values = self.values(request)
            if node in values:
                came_by(ctx, arrived, since, since + wait, what, "R-RCTP-32")
                await self.probe.answer(request, status, reason)
                return values
            await self.probe.answer(request)
        raise never_came(ctx, since, since + wait, loop.time(), what, "R-RCTP-32", "none")

    async def quiet(self) -> list[Request]:
        """The server's requests for `_SETTLE` (the robot's own changes may never stop), each
        answered 200."""
        seen: list[Request] = []
        deadline = asyncio.get_running_loop().time() + _SETTLE * self.ctx.scale
        while (left := deadline - asyncio.get_running_loop().time()) > 0:
            request = await self.next(left)
            if request is None:
                break
            seen.append(request)
            await self.probe.answer(request)
        return seen

    async def ask(self, method: str, body: bytes = b"") -> tuple[Response, list[Request]]:
        """A request of the watcher, its answer, and the server's requests that came first
        (answered 200): `ControlProbe.request` would answer and hide them."""
        named = self.named
        fields = named.fields() if method in ("READ", "WRITE") else []
        await self.probe.send(self.probe.request_bytes(method, named.target, fields, body))
        seen: list[Request] = []
        while True:
            message = await self.probe.message()
            if message is None:
                raise Failed("R-RCTP-5", f"an answer to {method}", "the connection closed")
            if isinstance(message, Response):
                return message, seen
            seen.append(self._take(message))
            await self.probe.answer(message)

    def none_listing(self, seen: list[Request], rule: str, when: str) -> None:
        """None of `seen` is a WRITE of the access listing the node."""
        named = self.named
        for request in seen:
            pushed = request.method == "WRITE" and parse_target(request.target).path == named.path
            listed = named.node.name in self.values(request) if pushed else False
            shown = f"WRITE {request.target} [Nodes: {request.headers.get('Nodes')}]"
            self.ctx.expect(not listed, f"no WRITE of {named.node.name} {when}", shown, rule)


class _Scene:
    """What an event case changes and watches: a readable and writable node of an event access
    (`_changing`), a session that writes it (`by`, holding its privilege unless not `hold`), its
    value before the case and `count` others to write, and the watchers where the access plays
    (the first started with the scene, `watch` starts more)."""

    def __init__(
        self, ctx: Context, named: Named, by: ControlProbe, before: Value, values: list[Value]
    ) -> None:
        self.ctx, self.named, self.by = ctx, named, by
        self.before, self.values = before, values
        self.watchers: list[_Watcher] = []

    @classmethod
    async def open(cls, ctx: Context, count: int, *, hold: bool = True) -> _Scene:
        named = _changing(ctx, count)
        by = await writer(ctx, named) if hold else (await sessions(ctx, 1))[0]
        before = (await read(ctx, by, named))[named.node.name]
        scene = cls(ctx, named, by, before, other_values(named.node, before, count))
        await scene.watch()
        return scene

    @property
    def watcher(self) -> _Watcher:
        return self.watchers[0]

    async def watch(self) -> None:
        self.watchers.append(await _Watcher.start(self.ctx, self.named))

    async def change(self, value: Value) -> None:
        """`by` writes `value` (a precondition: the rctp/node cases check WRITE)."""
        named = self.named
        answer = await write(self.by, named, {named.node.name: value})
        if answer.status != 200:
            raise Inconclusive(f"WRITE {named.path} was answered {answer.status} {answer.reason}")

    def expect_value(self, values: dict[str, Value], value: Value) -> None:
        """The values of a pushed WRITE give the node `value`."""
        node = self.named.node
        pushed = values.get(node.name)
        self.ctx.expect(pushed == value, _shown(node, value), _shown(node, pushed), "R-RCTP-32")

    async def end(self) -> None:
        """Close the watchers, then write back the value found."""
        for watcher in self.watchers:
            watcher.probe.close()
        await put_back(self.ctx, self.by, self.named, {self.named.node.name: self.before})


@case(
    "rctp/event/push",
    "A change of a playing event access's node is pushed as WRITE with the session and CSeq 1",
    ["R-RCTP-32", "R-RCTP-4", "R-RCTP-19", "R-RCTP-30", "R-RCTP-6"],
    serial=True,
)
async def push(ctx: Context) -> None:
    scene = await _Scene.open(ctx, 1)
    (value,) = scene.values
    await scene.change(value)
    values = await scene.watcher.push()
    await scene.end()
    scene.expect_value(values, value)


@case(
    "rctp/event/push-numbering",
    "The server numbers its WRITEs to a session 1, 2, 3, one change after another",
    ["R-RCTP-4", "R-RCTP-32"],
    serial=True,
)
async def push_numbering(ctx: Context) -> None:
    scene = await _Scene.open(ctx, 3)
    for value in scene.values:  # each WRITE's CSeq is checked as it comes (_Watcher)
        await scene.change(value)
        scene.expect_value(await scene.watcher.push(), value)
    await scene.end()


@case(
    "rctp/event/push-sessions",
    "Every session where the access plays gets the change, with its own Session and CSeq",
    ["R-RCTP-32", "R-RCTP-19", "R-RCTP-4"],
    serial=True,
)
async def push_sessions(ctx: Context) -> None:
    scene = await _Scene.open(ctx, 1)
    (value,) = scene.values
    await scene.watch()
    await scene.change(value)
    for watcher in scene.watchers:
        scene.expect_value(await watcher.push(), value)
    await scene.end()


@case(
    "rctp/event/push-refused",
    "A WRITE the client answers 455 does not stop the session: the next change is pushed too",
    ["R-RCTP-32", "R-RCTP-4"],
    serial=True,
)
async def push_refused(ctx: Context) -> None:
    scene = await _Scene.open(ctx, 2)
    first, second = scene.values
    watcher = scene.watcher
    await scene.change(first)
    await watcher.push(455, "Method Not Valid in This State")
    await scene.change(second)
    values = await watcher.push()
    answer, _ = await watcher.ask("READ")
    await scene.end()
    scene.expect_value(values, second)
    ctx.expect_status(answer, 200, "R-RCTP-32")


@case(
    "rctp/event/pause",
    "After PAUSE no change is pushed; after GO again, the next change is",
    ["R-RCTP-32"],
    serial=True,
)
async def pause(ctx: Context) -> None:
    scene = await _Scene.open(ctx, 2)
    first, second = scene.values
    watcher = scene.watcher
    paused, _ = await watcher.ask("PAUSE")
    if paused.status != 200:
        raise Inconclusive(f"PAUSE was answered {paused.status} {paused.reason}")
    await scene.change(first)
    seen = await watcher.quiet()
    again, late = await watcher.ask("GO")
    watcher.none_listing(seen + late, "R-RCTP-32", "while paused")
    if again.status != 200:
        raise Inconclusive(f"GO after PAUSE was answered {again.status} {again.reason}")
    await scene.change(second)
    values = await watcher.push()
    await scene.end()
    scene.expect_value(values, second)


@case(
    "rctp/event/stop",
    "After STOP no change is pushed, and GO without a new SETUP is answered 455",
    ["R-RCTP-32", "R-RCTP-20"],
    serial=True,
)
async def stop(ctx: Context) -> None:
    scene = await _Scene.open(ctx, 1)
    watcher = scene.watcher
    stopped, _ = await watcher.ask("STOP")
    if stopped.status != 200:
        raise Inconclusive(f"STOP was answered {stopped.status} {stopped.reason}")
    await scene.change(scene.values[0])
    seen = await watcher.quiet()
    go, late = await watcher.ask("GO")
    await scene.end()
    watcher.none_listing(seen + late, "R-RCTP-32", "after STOP")
    ctx.expect_status(go, 455, "R-RCTP-20")


@case(
    "rctp/event/no-echo",
    "A session's own WRITE is not pushed back to it; another session's later change is",
    ["R-RCTP-54", "R-RCTP-32"],
    serial=True,
)
async def no_echo(ctx: Context) -> None:
    scene = await _Scene.open(ctx, 2, hold=False)  # the watcher writes first
    first, second = scene.values
    named, watcher = scene.named, scene.watcher
    acquired, early = await watcher.ask("ACQUIRE")
    if acquired.status != 200:
        raise Inconclusive(f"ACQUIRE {named.path} was answered {acquired.status}")
    written, during = await watcher.ask("WRITE", named.encode({named.node.name: first}))
    if written.status != 200:
        raise Inconclusive(f"WRITE {named.path} was answered {written.status} {written.reason}")
    seen = early + during + await watcher.quiet()
    released, late = await watcher.ask("RELEASE")
    watcher.none_listing(seen + late, "R-RCTP-54", "after the session's own WRITE")
    if released.status != 200:
        raise Inconclusive(f"RELEASE was answered {released.status} {released.reason}")
    await acquire(ctx, scene.by, named.path)
    await scene.change(second)
    values = await watcher.push()
    await scene.end()
    scene.expect_value(values, second)


@case(
    "rctp/event/at-most-four",
    "A client that does not answer has at most four WRITEs outstanding; then it gets the newest",
    ["R-RCTP-55", "R-RCTP-32"],
    serial=True,
)
async def at_most_four(ctx: Context) -> None:
    scene = await _Scene.open(ctx, _FLOOD)
    named, watcher, values = scene.named, scene.watcher, scene.values
    for value in values:
        await scene.change(value)
        await asyncio.sleep(_GAP * ctx.scale)
    unanswered: list[Request] = []
    while (request := await watcher.next(_SETTLE * ctx.scale)) is not None:
        unanswered.append(request)
    writes = [r for r in unanswered if r.method == "WRITE"]
    count = sum(1 for r in unanswered if r.method in ("WRITE", "STOP"))  # BYE is not held back
    ctx.expect(count <= 4, "at most 4 WRITE and STOP unanswered", f"{count}", "R-RCTP-55")
    ctx.expect(bool(writes), f"a WRITE of {named.path}", "none", "R-RCTP-32")
    pushed = [watcher.values(r).get(named.node.name) for r in writes]
    for request in unanswered:
        await watcher.probe.answer(request)
    # What waited is sent merged once there is room, with the newest value.
    last, newest = pushed[-1], values[-1]
    while last != newest:
        more = len(watcher.seen) - len(unanswered)
        ctx.expect(
            more <= _FLOOD, _shown(named.node, newest), _shown(named.node, last), "R-RCTP-32"
        )
        last = (await watcher.push()).get(named.node.name)
    await scene.end()


@case(
    "rctp/event/server-methods",
    "While pushing changes, the server sends no request but WRITE, STOP and BYE",
    ["R-RCTP-25", "R-RCTP-32"],
    serial=True,
)
async def server_methods(ctx: Context) -> None:
    scene = await _Scene.open(ctx, 3)
    for value in scene.values:
        await scene.change(value)
    # The first push within its bound, then every request until none comes within the bound:
    # each is checked by `_Watcher._take`.
    await scene.watcher.push()
    await scene.watcher.quiet()
    await scene.end()
