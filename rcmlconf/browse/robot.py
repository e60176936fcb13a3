"""One page's session with one robot, over the reference client (`reference.client.adapter`):
connect, set up what the panel links to (`links`), follow the robot for the page, apply the
user's input, and reconnect when the server comes back.

The privilege (D-RCTP-16): an autoStart stream the panel writes asks for it, so its access node is
ACQUIREd first and the stream set up to write; when another session holds it (471) the stream is
set up to read only and the refusal shown on the widgets that write. An actionButton's ACQUIRE
turns the streams below its target to writing, its RELEASE turns them back first (a writing
stream below a released path is 455, D-RCTP-16), and releases what the session holds at or below
the target. Mode changes are PAUSE, SETUP, GO: SETUP of a playing stream is 455 (D-RCTP-14).
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections.abc import Awaitable, Callable, Mapping
from dataclasses import dataclass

from rcmlconf.browse.links import NORMAL_READ_EVERY, AccessUse, RobotLinks
from rcmlconf.browse.messages import Input
from rcmlconf.browse.outbox import Outbox
from rcmlconf.browse.panel import PanelWidget, checkbox_values, shown
from rcmlconf.errors import ValueTextError
from rcmlconf.rcml.model import AccessNode, AccessType, DataNode
from rcmlconf.rcml.url import RctpUrl
from rcmlconf.rctp.datastream.clock import unix_from_ntp
from rcmlconf.reference.client.adapter import Client, RctpError
from rcmlconf.reference.client.session import (
    Closed,
    ServerRequest,
    StreamLost,
    StreamValues,
)
from rcmlconf.values import Value, parse_value_text

#: Seconds between attempts to reach a server that is not there (or has gone).
RETRY_EVERY = 1.0
#: R-RCTP-23: BYE's answer is awaited this long before the connection is closed anyway.
BYE_WAIT = 5.0
#: Requests waiting for the robot at most, per session (writes to one node merge into one).
MAX_WAITING = 64
#: D-RCTP-15's refusals a panel meets, in words (the answer itself follows in brackets).
WORDS = {
    403: "forbidden: the robot's permission does not allow it",
    422: "refused: the robot does not take that value",
    455: "not now: the access is not in a state for it",
    470: "not acquired: take control first",
    471: "busy: another session has control",
}

log = logging.getLogger("rcmlconf.browse")


def under(path: str, top: str) -> bool:
    """Whether `path` is `top` or below it."""
    return top == "/" or path == top or path.startswith(top + "/")


def refusal_text(exc: RctpError) -> str:
    status = exc.response.status if exc.response is not None else None
    words = WORDS.get(status) if status is not None else None
    return f"{words} ({exc})" if words else str(exc)


@dataclass(frozen=True, slots=True)
class _Job:
    """A request for the robot from the user: a WRITE or an actionButton's method."""

    widget: PanelWidget
    run: Callable[[Client], Awaitable[None]]


class RobotSession:
    def __init__(
        self,
        links: RobotLinks,
        url: RctpUrl,
        widgets: tuple[PanelWidget, ...],
        outbox: Outbox,
        timeout: float,
    ) -> None:
        self.links = links
        self.robot = links.robot
        self.url = url
        self.widgets = widgets
        self.outbox = outbox
        self.timeout = timeout
        self.client: Client | None = None
        #: Paths whose privilege the session holds (ACQUIREd, not RELEASEd).
        self.held: set[str] = set()
        #: Stream access path -> the mode it is set up with; and those playing.
        self.modes: dict[str, str] = {}
        self.playing: set[str] = set()
        #: Stream access path -> node name -> the user's value, written every interval.
        self.written: dict[str, dict[str, Value]] = {}
        #: Streams set up to write whose values go out every interval (`_start_writing`).
        self.writing: set[str] = set()
        self._jobs: dict[object, _Job] = {}
        self._job_ready = asyncio.Event()
        #: Paced accesses (`_show`): when the page was last told, what waits, and the timer.
        self._paced: dict[str, float] = {}
        self._waiting: dict[str, dict[str, str]] = {}
        self._waiting_sent: dict[str, float] = {}
        self._later: dict[str, asyncio.TimerHandle] = {}
        #: Access path -> its data nodes by name (`_nodes_of`).
        self._nodes: dict[str, dict[str, DataNode]] = {}
        #: Set when the user's BYE ends the session: it stays closed until a `connect` action.
        self._parked = False
        self._wake = asyncio.Event()

    # -- the session's life ------------------------------------------------------------------

    async def run(self) -> None:
        """Connect, serve the page, reconnect; until cancelled, which says BYE (R-RCTP-23)."""
        attempt = 0
        while True:
            if self._parked:
                await self._wake.wait()
                self._parked = False
            self._wake.clear()
            self._state("connecting" if attempt == 0 else "reconnecting")
            try:
                client = await Client.connect(self.url, self.links.model, timeout=self.timeout)
            except RctpError as exc:
                attempt += 1
                self._state("waiting", f"{exc}; trying again every {RETRY_EVERY:g} s")
                await self._pause_or_wake(RETRY_EVERY)
                continue
            attempt = 1
            self.client = client
            try:
                reason = await self._serve(client)
            finally:
                self.client = None
                self._forget()
                await client.close(BYE_WAIT)
            self._state("closed", reason)
            if not self._parked:
                await self._pause_or_wake(RETRY_EVERY)

    async def _pause_or_wake(self, seconds: float) -> None:
        with contextlib.suppress(TimeoutError):
            await asyncio.wait_for(self._wake.wait(), seconds)

    def _forget(self) -> None:
        self.held.clear()
        self.modes.clear()
        self.playing.clear()
        self.written.clear()
        self.writing.clear()
        self._jobs.clear()
        for handle in self._later.values():
            handle.cancel()
        self._later.clear()
        self._waiting.clear()
        self._waiting_sent.clear()

    def _state(self, state: str, detail: str | None = None) -> None:
        log.info("%s: %s%s", self.robot, state, f" ({detail})" if detail else "")
        self.outbox.note("state", robot=self.robot, state=state, detail=detail)

    async def _serve(self, client: Client) -> str:
        self._state("connected", str(self.url))
        tasks = [
            asyncio.ensure_future(self._follow(client)),
            asyncio.ensure_future(self._poll(client)),
            asyncio.ensure_future(self._work(client)),
        ]
        try:
            await self._open(client)
            done, _ = await asyncio.wait(tasks, return_when=asyncio.FIRST_COMPLETED)
            return next(iter(done)).result() or "the session ended"
        finally:
            for task in tasks:
                task.cancel()
            await asyncio.gather(*tasks, return_exceptions=True)

    # -- opening the window (D-RXID-8) -------------------------------------------------------

    async def _open(self, client: Client) -> None:
        for use in self.links.accesses.values():
            if not use.starts:
                continue
            try:
                if use.streams:
                    await self._start_stream(client, use)
                else:
                    await self._start_event(client, use.path)
            except RctpError as exc:
                self._refuse_access(use.path, refusal_text(exc))

    async def _start_stream(self, client: Client, use: AccessUse) -> None:
        if use.writes and not self._covered(use.path):
            try:
                await client.acquire(use.path)
                self.held.add(use.path)
            except RctpError as exc:
                self._refuse_access(use.path, refusal_text(exc), writers_only=True)
        mode = use.mode(self._covered(use.path))
        if mode is not None:
            await client.setup(use.path, mode)
            self.modes[use.path] = mode
            self._start_writing(client, use.path)
            await client.go(use.path)
            self.playing.add(use.path)

    async def _start_event(self, client: Client, path: str) -> None:
        await client.setup(path)
        await client.go(path)
        # D-RCTP-27: GO sends nothing; the state is READ after it.
        self._show(path, await client.read(path), paced=False)

    def _covered(self, path: str) -> bool:
        return any(under(path, top) for top in self.held)

    def _refuse_access(self, path: str, text: str, writers_only: bool = False) -> None:
        for widget in self.widgets:
            link = widget.link
            if link is not None and link.access.path == path and (link.writes or not writers_only):
                self.outbox.note("refusal", widget=widget.key, text=text)

    # -- following the robot -----------------------------------------------------------------

    async def _follow(self, client: Client) -> str:
        while True:
            event = await client.next_event()
            if event is None or isinstance(event, Closed):
                return client.closed.reason if client.closed else "the session ended"
            if isinstance(event, StreamValues):
                self._show(event.path, event.values, paced=True, sent=unix_from_ntp(event.sent))
                self._start_writing(client, event.path)
            elif isinstance(event, ServerRequest):
                self._server_request(event)
            elif isinstance(event, StreamLost):
                self.outbox.note("stream", robot=self.robot, path=event.path, state="lost")

    def _server_request(self, event: ServerRequest) -> None:
        if event.method == "WRITE" and event.values is not None:
            self._show(event.path, event.values, paced=False)  # D-RCTP-27
        elif event.method == "STOP":
            self.modes.pop(event.path, None)
            self.writing.discard(event.path)
            self.playing.discard(event.path)
            self.outbox.note(
                "stream", robot=self.robot, path=event.path, state="stopped", detail=event.reason
            )

    async def _poll(self, client: Client) -> str:
        """The normal accesses' nodes a widget shows, READ every NORMAL_READ_EVERY."""
        nodes = self.links.polled
        while nodes:
            for node in nodes:
                try:
                    self._show(node.path.rsplit("/", 1)[0], await client.read(node.path), False)
                except RctpError as exc:
                    self._refuse_node(node.path, refusal_text(exc))
            await asyncio.sleep(NORMAL_READ_EVERY)
        await asyncio.Event().wait()  # nothing to poll: until the session ends
        return ""

    def _show(
        self,
        access_path: str,
        values: Mapping[str, Value],
        paced: bool,
        sent: float | None = None,
    ) -> None:
        """The access's values to the page; when `paced`, at most once per the access's pace
        (D-RXID-8), values meanwhile merged and the newest kept."""
        by_name = self._nodes_of(access_path)
        if not by_name:
            return
        texts = {by_name[k].path: shown(by_name[k], v) for k, v in values.items() if k in by_name}
        use = self.links.accesses.get(access_path)
        if not paced or use is None or use.pace <= 0:
            self.outbox.values(self.robot, texts, sent)
            return
        self._waiting.setdefault(access_path, {}).update(texts)
        if sent is not None:
            self._waiting_sent[access_path] = sent
        if access_path in self._later:
            return
        loop = asyncio.get_running_loop()
        due = self._paced.get(access_path, -use.pace) + use.pace
        if loop.time() >= due:
            self._flush_later(access_path)
        else:
            self._later[access_path] = loop.call_at(due, self._flush_later, access_path)

    def _nodes_of(self, access_path: str) -> dict[str, DataNode]:
        """An access's data nodes by name (none for a path that is no access): made once, not
        at each of a stream's DATA; only the model's accesses are kept, so nothing grows."""
        nodes = self._nodes.get(access_path)
        if nodes is None:
            access = self.links.model.node(access_path)
            if not isinstance(access, AccessNode):
                return {}
            nodes = self._nodes[access_path] = {n.name: n for n in access.data}
        return nodes

    def _flush_later(self, access_path: str) -> None:
        self._later.pop(access_path, None)
        self._paced[access_path] = asyncio.get_running_loop().time()
        texts = self._waiting.pop(access_path, None)
        if texts:
            self.outbox.values(self.robot, texts, self._waiting_sent.pop(access_path, None))

    def _refuse_node(self, path: str, text: str) -> None:
        for widget in self.widgets:
            if widget.link is not None and widget.link.node.path == path:
                self.outbox.note("refusal", widget=widget.key, text=text)

    # -- the user's input ----------------------------------------------------------------------

    def input(self, message: Input) -> None:
        widget, link = message.widget, message.widget.link
        assert link is not None  # messages.parse_message: an input names a widget that writes
        text = self._value_text(widget, message.value)
        if text is None:
            return
        node = link.node
        try:
            value = parse_value_text(node.type.base, text, node.type.size)
        except ValueTextError as exc:
            self.outbox.note(
                "refusal", widget=widget.key, text=f"not a value of {node.path}: {exc}"
            )
            return
        problem = node.out_of_range(value)
        if problem is not None:
            self.outbox.note("refusal", widget=widget.key, text=problem)
            return
        if link.access.type is AccessType.STREAM:
            self._write_stream(widget, link.access, node, value)
        else:
            self._queue(node.path, widget, lambda c: c.write(node.path, {node.name: value}))

    def _value_text(self, widget: PanelWidget, value: str) -> str | None:
        """What a button or checkbox input writes (D-RXID-6); other widgets' value as sent."""
        if widget.kind == "button":
            return (
                widget.attribute("value") if value == "press" else widget.attribute("releaseValue")
            )
        if widget.kind == "checkbox":
            on, off = checkbox_values(widget)
            return on if value == "on" else off
        return value

    def _write_stream(
        self, widget: PanelWidget, access: AccessNode, node: DataNode, value: Value
    ) -> None:
        client = self.client
        if client is None or self.modes.get(access.path) not in ("write", "both"):
            text = f"{WORDS[470]}: {access.path} is not set up for writing"
            self.outbox.note("refusal", widget=widget.key, text=text)
            return
        self.written.setdefault(access.path, {})[node.name] = value
        self._start_writing(client, access.path)
        self.outbox.note("accepted", widget=widget.key)

    def _start_writing(self, client: Client, path: str) -> None:
        """A stream set up to write sends every interval from the start, or the server STOPs it
        at its write timeout (D-RCTP-23); a node the user has not moved is written as the robot
        has it, so the robot's values come first: after the first DATA when the stream reads."""
        if path in self.writing or self.modes.get(path) not in ("write", "both"):
            return  # at every DATA of a stream that writes already: nothing more to look up
        access = self.links.model.node(path)
        assert isinstance(access, AccessNode)  # modes holds stream accesses only
        if access.readable() and path not in client.session.received:
            return  # `_show` comes back with the first values
        self.writing.add(path)
        client.write_values(path, lambda: self._stream_values(client, access))

    def _stream_values(self, client: Client, access: AccessNode) -> dict[str, Value]:
        """D-RCTP-20: every writable node, each interval: the user's value, else the robot's
        latest, else the node's zero."""
        written = self.written.get(access.path, {})
        received = client.session.received.get(access.path, {})
        return {
            n.name: written.get(n.name, received.get(n.name, n.zero())) for n in access.writable()
        }

    # -- actionButtons (D-RXID-7) --------------------------------------------------------------

    def action(self, widget: PanelWidget) -> None:
        action, target = widget.attribute("action"), widget.element.path
        if action == "connect":
            if self.client is not None:
                self.outbox.note("refusal", widget=widget.key, text="already connected")
                return
            self._parked = False
            self._wake.set()  # at once, not at the next attempt
            self.outbox.note("accepted", widget=widget.key)
            return
        if action == "bye":
            self._parked = True
            self._queue(("bye",), widget, self._bye)
            return
        assert action is not None, "R-RXID-27: validated"
        assert target is not None, "R-RXID-24: validated"
        method = _ACTIONS[action]
        self._queue((action, target), widget, lambda c: method(self, c, target))

    async def _bye(self, client: Client) -> None:
        await client.close(BYE_WAIT)

    async def _acquire(self, client: Client, target: str) -> None:
        await client.acquire(target)
        self.held = {h for h in self.held if not under(h, target)} | {target}
        for path in list(self.modes):
            if under(path, target):
                await self._remode(client, path)

    async def _release(self, client: Client, target: str) -> None:
        paths = [h for h in self.held if under(h, target)] or [target]
        self.held -= set(paths)
        for path in list(self.modes):
            if any(under(path, p) for p in paths):
                await self._remode(client, path)
        for path in paths:
            await client.release(path)

    async def _setup(self, client: Client, target: str) -> None:
        use = self.links.accesses.get(target)
        node = self.links.model.node(target)
        streams = isinstance(node, AccessNode) and node.type is AccessType.STREAM
        mode = (use.mode(self._covered(target)) if use else None) or "read"
        await client.setup(target, mode)
        if streams:
            self.modes[target] = mode
            self._start_writing(client, target)

    async def _go(self, client: Client, target: str) -> None:
        await client.go(target)
        node = self.links.model.node(target)
        if isinstance(node, AccessNode) and node.type is AccessType.EVENT:
            self._show(target, await client.read(target), paced=False)  # D-RCTP-27
        else:
            self.playing.add(target)

    async def _pause(self, client: Client, target: str) -> None:
        await client.pause(target)
        self.playing.discard(target)

    async def _stop(self, client: Client, target: str) -> None:
        await client.stop(target)
        self.modes.pop(target, None)
        self.playing.discard(target)
        self.written.pop(target, None)
        self.writing.discard(target)

    async def _remode(self, client: Client, path: str) -> None:
        """A stream set up again with the mode the privilege allows now: PAUSE, SETUP, GO."""
        use = self.links.accesses.get(path)
        mode = use.mode(self._covered(path)) if use is not None else None
        if mode is None or mode == self.modes.get(path):
            return
        playing = path in self.playing
        if playing:
            await client.pause(path)
        await client.setup(path, mode)
        self.modes[path] = mode
        self.writing.discard(path)
        self._start_writing(client, path)
        if playing:
            await client.go(path)

    # -- the queue of requests -----------------------------------------------------------------

    def _queue(
        self, key: object, widget: PanelWidget, run: Callable[[Client], Awaitable[None]]
    ) -> None:
        """A request for the robot, after those waiting; one waiting for the same node or the
        same action is replaced (its newer value is what the user wants)."""
        if self.client is None:
            self.outbox.note("refusal", widget=widget.key, text="not connected to the robot")
            return
        if key not in self._jobs and len(self._jobs) >= MAX_WAITING:
            self.outbox.note("refusal", widget=widget.key, text="too many requests waiting")
            return
        self._jobs.pop(key, None)
        self._jobs[key] = _Job(widget, run)
        self._job_ready.set()

    async def _work(self, client: Client) -> str:
        while True:
            while not self._jobs:
                self._job_ready.clear()
                await self._job_ready.wait()
            key = next(iter(self._jobs))
            job = self._jobs.pop(key)
            try:
                await job.run(client)
            except RctpError as exc:
                self.outbox.note("refusal", widget=job.widget.key, text=refusal_text(exc))
            else:
                self.outbox.note("accepted", widget=job.widget.key)
            if client.closed is not None:
                return client.closed.reason


_Method = Callable[[RobotSession, Client, str], Awaitable[None]]
_ACTIONS: dict[str, _Method] = {
    "acquire": RobotSession._acquire,
    "release": RobotSession._release,
    "setup": RobotSession._setup,
    "go": RobotSession._go,
    "pause": RobotSession._pause,
    "stop": RobotSession._stop,
}
