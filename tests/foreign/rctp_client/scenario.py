"""D-RCTP-31: the conformance scenario of a client, steps 2 to 8 (step 1, the files, is
main.py's). Every request goes through Session.call; the server's requests are answered by
the session whenever they arrive."""

from __future__ import annotations

from typing import Any

from rcml import BadValue, Model, Node, text, zero
from session import Access, Closed, Session
from wire import Message, encode_segment

EVENT_TIME = 1.0  # step 5
PLAY_TIME, PAUSE_TIME, REPLAY_TIME = 1.5, 0.25, 0.5  # step 6


class Ended(Exception):
    """The run ends: the server's BYE, the connection gone, no answer in 5 s."""


class Interrupted(Exception):
    """SIGINT or SIGTERM: BYE, then exit."""


class Scenario:
    def __init__(self, session: Session, model: Model) -> None:
        self.s = session
        self.model = model
        nodes = model.root.walk()  # document order
        self.normal = [
            n for n in nodes if n.kind == "data" and n.parent and n.parent.atype == "normal"
        ]
        self.events = [n for n in nodes if n.kind == "access" and n.atype == "event"]
        self.streams = [n for n in nodes if n.kind == "access" and n.atype == "stream"]
        self.read_failed: set[str] = set()  # event accesses whose READ failed
        self.privileged = False

    async def run(self) -> None:
        s = self.s
        try:
            if not await s.connect():
                return  # step 2: an answer other than 200 ends the run
            await self.read_step()
            await self.write_step()
            await self.event_step()
            await self.stream_step()
            await self.clock_step()
            if "request-after-bye" not in s.faults:
                await self.call("RELEASE", "*")  # step 8
            self.check()
            await s.bye()
        except Interrupted:
            await s.bye()
        except (Ended, Closed) as e:
            s.log(f"the run ended: {e or 'the session ended'}")

    def check(self) -> None:
        if self.s.stop.is_set() and self.s.state == "open":
            raise Interrupted
        if self.s.closed or self.s.state != "open":
            raise Ended("the session ended")

    async def call(
        self,
        method: str,
        target: str,
        fields: list[tuple[str, str]] | None = None,
        body: bytes = b"",
    ) -> Message:
        self.check()
        msg = await self.s.call(method, target, fields, body)
        if msg.status != 200:
            self.s.log(f"{method} {target}: {msg.status} {msg.reason}", always=True)
        return msg

    # ---- step 3 -------------------------------------------------------------------------------

    async def read_step(self) -> None:
        for node in self.normal:
            if node.readable:
                await self.read(node)
        for access in self.events:
            if access.data_nodes("r"):
                await self.read(access)

    async def read(self, node: Node) -> None:
        msg = await self.call("READ", node.path)
        if node.kind == "access":
            self.read_failed.add(node.path)
        if msg.status != 200:
            return
        nodes = [node] if node.kind == "data" else self.s.nodes_field(node, msg.get("Nodes"))
        try:
            if nodes is None:
                raise BadValue("no usable Nodes field")
            if not self.s.is_values(msg.get("Content-Type")):
                raise BadValue(f"Content-Type {msg.get('Content-Type')!r}")
            values = self.s.codec.decode(nodes, msg.body)
        except BadValue as e:
            self.s.log(f"READ {node.path}: a body that does not decode ({e})", always=True)
            return
        for n, v in zip(nodes, values, strict=True):
            self.s.values[n.path] = v
            self.s.log(f"  {n.path} = {text(v)}")
        self.read_failed.discard(node.path)

    # ---- step 4 -------------------------------------------------------------------------------

    def value_of(self, node: Node) -> tuple[bool, Any]:
        """What a WRITE sends a node: the newest value known of it, its zero value when it
        cannot be read; (False, None) when its READ failed or did not decode."""
        if not node.readable:
            return True, zero(node)
        if node.path in self.s.values:
            return True, self.s.values[node.path]
        return False, None

    async def write_step(self) -> None:
        if not any(n.writable for n in self.model.root.walk() if n.kind == "data"):
            return  # a robot with nothing writable: the privilege is never needed
        self.privileged = (await self.call("ACQUIRE", "/")).status == 200
        if not self.privileged:
            return  # every WRITE needs the privilege (D-RCTP-16)
        for node in self.normal:
            if node.writable:
                ok, value = self.value_of(node)
                if ok:
                    await self.call("WRITE", node.path, [], self.s.codec.encode([node], [value]))
        for access in self.events:
            await self.write_event(access)

    async def write_event(self, access: Node) -> None:
        nodes = access.data_nodes("w")
        if not nodes or not self.privileged or access.path in self.read_failed:
            return
        if any(n.path not in self.s.values for n in access.data_nodes("r")):
            return  # a node whose READ gave nothing: the access is not written
        if "nodes-document-order" in self.s.faults:
            nodes.sort(key=lambda n: n.doc_index)
        values = [self.value_of(n)[1] for n in nodes]
        names = ", ".join(encode_segment(n.name) for n in nodes)
        body = self.s.codec.encode(nodes, values)
        await self.call("WRITE", access.path, [("Nodes", names)], body)

    # ---- step 5 -------------------------------------------------------------------------------

    async def event_step(self) -> None:
        for access in self.events:
            self.check()
            acc = await self.s.setup(access)
            if acc is not None:  # no GO, PAUSE or STOP after a failed SETUP
                if await self.s.go(acc):
                    await self.wait(EVENT_TIME, acc)  # data-change WRITEs come meanwhile
                if acc.stopped:
                    continue  # the server's STOP ends this access's step at once
                self.check()
                await self.s.pause(acc)
                if acc.stopped:
                    continue
            await self.write_event(access)
            if acc is not None and not acc.stopped:
                self.check()
                await self.s.stop_access(acc)

    async def wait(self, seconds: float, acc: Access) -> None:
        if not await self.s.wait(seconds, acc) and not acc.stopped:
            self.check()

    # ---- step 6 -------------------------------------------------------------------------------

    async def stream_step(self) -> None:
        for access in self.streams:
            reads, writes = access.data_nodes("r"), access.data_nodes("w")
            if not reads and not writes:
                continue
            mode = "both" if reads and writes else "read" if reads else "write"
            self.check()
            acc = await self.s.setup(access, mode)
            if acc is not None:  # no GO after a failed SETUP
                await self.play(acc)
            self.s.log(f"stream {access.path}: {acc.packets if acc else 0} DATA payloads applied")

    async def play(self, acc: Access) -> None:
        """GO, 1.5 s, PAUSE, 0.25 s, GO, 0.5 s, STOP; a server STOP ends it at once."""
        if await self.s.go(acc):
            await self.wait(PLAY_TIME, acc)
        for step in ("pause", "wait", "go", "stop"):
            if acc.stopped:
                return
            self.check()
            if step == "pause":
                await self.s.pause(acc)
            elif step == "wait":
                await self.wait(PAUSE_TIME, acc)
            elif step == "go":
                if await self.s.go(acc):
                    await self.wait(REPLAY_TIME, acc)
            else:
                await self.s.stop_access(acc)

    # ---- step 7 -------------------------------------------------------------------------------

    async def clock_step(self) -> None:
        clock = next(
            (
                a
                for a in self.model.root.walk()
                if a.kind == "access" and a.atype == "normal" and a.name == "clock"
            ),
            None,
        )
        if clock is None:
            return
        nodes = [clock.children.get("offset"), clock.children.get("uncertainty")]
        if any(
            n is None or n.kind != "data" or n.dtype != "float64" or not n.writable for n in nodes
        ):
            return
        estimate = self.s.clock.estimate()
        if estimate is None or not self.privileged:
            return  # no heartbeat answered: nothing to say
        offset, uncertainty = estimate
        if "clock-offset-negated" in self.s.faults:
            offset = -offset
        self.s.log(f"robot clock - ours = {offset:+.6f} s +- {uncertainty:.6f} s", always=True)
        for node, value in zip(nodes, (offset, uncertainty), strict=True):
            assert node is not None
            await self.call("WRITE", node.path, [], self.s.codec.encode([node], [value]))
