"""The conformance scenario of a client (specs/rctp-2.0.md D-RCTP-31), run by the reference client.

A harness that plays the server gives a client one case URL, `rctp://HOST:PORT/PATH`, and the
client does the same things every time: it fetches the case's files, connects, reads, writes,
plays the event and stream accesses, writes its clock estimate and leaves. `run_scenario` does
that with `adapter.Client`, for the harness's client cases and `rcmlconf client URL scenario`.
"""

from __future__ import annotations

import asyncio
import enum
from collections.abc import Awaitable, Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import NoReturn, TypeVar

from rcmlconf.rcml.model import AccessNode, AccessType, DataNode, Permission, RcmlDocument
from rcmlconf.rcml.url import FILES_PORT_OFFSET, RctpUrl, http_base, parse_rctp_url
from rcmlconf.reference.client.adapter import Client, RctpError
from rcmlconf.reference.client.fetching import Deadline
from rcmlconf.reference.client.files import NoModel, from_index
from rcmlconf.reference.client.session import ClientEvent, Closed, ServerRequest
from rcmlconf.values import DATA_TYPES, Value, ValueType

T = TypeVar("T")

#: D-RCTP-31's times in seconds: step 5's wait for data-change WRITEs; step 6's heartbeats, play,
#: pause and second play.
EVENT_WAIT = 1.0
HEARTBEAT_EVERY = 1.0
PLAY, PAUSED, REPLAY = 1.5, 0.25, 0.5
#: The longest a run's steps take, and BYE's answer (R-RCTP-23), so that a run of a robot with
#: many nodes, or against a server slow to answer, is over in about 30 s.
LIMIT = 25.0
BYE_WAIT = 5.0
_FILES = "the case's files: D-RCTP-31, step 1"
_FLOAT64 = ValueType(DATA_TYPES["float64"])


class Ending(enum.Enum):
    COMPLETED = "completed"
    BYE = "ended by the server"
    REFUSED = "CONNECT refused"
    NO_FILES = "no files"
    NO_CONNECTION = "no connection"
    NO_ANSWER = "no answer"
    CLOSED = "closed"
    TOO_LONG = "cut short"


@dataclass(frozen=True, slots=True)
class ScenarioResult:
    #: The case URL.
    url: str
    ending: Ending
    #: What ended it: the BYE and its Reason, CONNECT's status, why the files could not be had.
    detail: str | None = None
    #: The requests answered with an error (or an answer the client could not use), after which
    #: the run went on.
    refused: tuple[str, ...] = ()

    @property
    def words(self) -> str:
        """For a log line: `completed`, `ended by the server (BYE, Reason: timeout)`, ..."""
        return self.ending.value if self.detail is None else f"{self.ending.value} ({self.detail})"

    def __str__(self) -> str:
        return f"{self.url}: {self.words}"


class _Ended(Exception):
    def __init__(self, ending: Ending, detail: str | None) -> None:
        super().__init__(detail)
        self.ending = ending
        self.detail = detail


class _Stopped(Exception):
    """The server STOPped the access whose step runs."""


async def run_scenario(
    url: RctpUrl | str,
    *,
    model: RcmlDocument | None = None,
    timeout: float = 5.0,
    limit: float = LIMIT,
) -> ScenarioResult:
    """Run D-RCTP-31's scenario once on the case `url` (ValueTextError if it is no RCTP URL).

    `model` is the robot's RCML, which skips step 1; `timeout` bounds each wait for the server
    (the decision's 5 s), `limit` the steps together. Whatever the server does, the result says
    how the run ended; a session, once open, ends with BYE.
    """
    case = parse_rctp_url(url) if isinstance(url, str) else url
    refused: list[str] = []
    try:
        async with asyncio.timeout(limit):
            if model is None:
                model = await _files(case, timeout)  # step 1
            client = await _connect(case, model, timeout)  # step 2
            try:
                await _Run(client, refused).steps(model)
            finally:
                await client.close(min(timeout, BYE_WAIT))  # step 8's BYE, however it ended
        ending, detail = Ending.COMPLETED, None
    except _Ended as ended:
        ending, detail = ended.ending, ended.detail
    except TimeoutError:
        ending, detail = Ending.TOO_LONG, f"not over after {limit:g} s"
    return ScenarioResult(str(case), ending, detail, tuple(refused))


def index_url(case: RctpUrl) -> str:
    """Step 1: a case's files index, at http://HOST:PORT+1/PATH/."""
    port = case.port_or_default + FILES_PORT_OFFSET
    return f"{http_base(case.host, port)}{case.path.rstrip('/')}/"


async def _files(case: RctpUrl, timeout: float) -> RcmlDocument:
    """Step 1, in a thread, so that the loop goes on while urllib waits: the index and the
    RCML within `timeout` together (a server may feed them a byte at a time), or the run's
    limit first."""
    pool = ThreadPoolExecutor(1, thread_name_prefix="scenario-files")
    try:
        fetched = pool.submit(from_index, index_url(case), Deadline(timeout), None, _FILES)
        return await asyncio.wrap_future(fetched)
    except NoModel as exc:
        raise _Ended(Ending.NO_FILES, str(exc)) from None
    finally:
        pool.shutdown(wait=False)


async def _connect(case: RctpUrl, model: RcmlDocument, timeout: float) -> Client:
    """Step 2: an answer other than 200 ends the run."""
    try:
        return await Client.connect(case, model, timeout=timeout, heartbeat_every=HEARTBEAT_EVERY)
    except RctpError as exc:
        if exc.response is None:
            raise _Ended(Ending.NO_CONNECTION, str(exc)) from None
        raise _Ended(Ending.REFUSED, f"{exc.response.status} {exc.response.reason}") from None


class _Run:
    """Steps 3 to 8 in one session."""

    def __init__(self, client: Client, refused: list[str]) -> None:
        self.client = client
        self.refused = refused
        #: Data node path -> the newest value read (step 3) or pushed (step 5).
        self.values: dict[str, Value] = {}
        #: Data nodes whose READ failed or did not decode: never written (step 4).
        self.failed: set[str] = set()
        #: Whether ACQUIRE `/` was granted: every WRITE, and SETUP for writing, need it
        #: (D-RCTP-16), so they are left out without it.
        self.acquired = False
        #: The access whose step runs, which a server STOP ends at once.
        self.playing: str | None = None

    async def steps(self, model: RcmlDocument) -> None:
        events = _accesses(model, AccessType.EVENT)
        for node in _nodes(model, Permission.READ):  # step 3
            _, read = await self._ask(self.client.read(node.path))
            self._note(read or {}, (node,))
        for access in events:
            if access.readable():
                _, read = await self._ask(self.client.read(access.path))  # without Nodes
                self._note(read or {}, access.readable())
        self.acquired = await self._ok(self.client.acquire("/"))  # step 4
        for node in _nodes(model, Permission.WRITE):
            value = self._value(node)
            if self.acquired and value is not None:
                await self._ok(self.client.write(node.path, {node.name: value}))
        for access in events:
            await self._write(access)
        for access in events:  # step 5
            await self._step(self._event, access)
        for access in _accesses(model, AccessType.STREAM):  # step 6
            await self._step(self._stream, access)
        await self._clock(model)  # step 7
        await self._ok(self.client.release("*"))  # step 8; BYE follows

    def _note(self, read: dict[str, Value], nodes: tuple[DataNode, ...]) -> None:
        for node in nodes:
            if node.name in read:
                self.values[node.path] = read[node.name]
            else:  # refused, undecodable, or left out of the answer's Nodes
                self.failed.add(node.path)

    def _value(self, node: DataNode) -> Value | None:
        """What steps 4 and 5 write a node: its newest value, or its zero value without `r`;
        None after a failed READ."""
        if Permission.READ not in node.permission:
            return node.zero()
        return self.values.get(node.path)

    async def _write(self, access: AccessNode) -> None:
        """Step 4's WRITE of an event access: every writable node, unless a node of the access
        failed to read."""
        if not self.acquired or any(node.path in self.failed for node in access.data):
            return
        values = {n.name: v for n in access.writable() if (v := self._value(n)) is not None}
        if values:  # in canonical order, as Nodes lists them (R-RCTP-30)
            await self._ok(self.client.write(access.path, values))

    async def _step(self, step: Callable[[AccessNode], Awaitable[None]], node: AccessNode) -> None:
        self.playing = node.path
        try:
            await step(node)
        except _Stopped:
            pass  # a server STOP ends the access's step at once
        finally:
            self.playing = None

    async def _event(self, access: AccessNode) -> None:
        """Step 5: SETUP, GO, the server's data-change WRITEs for 1 s, PAUSE, step 4's WRITE
        with the newest values, STOP."""
        set_up = await self._ok(self.client.setup(access.path))
        if set_up and await self._ok(self.client.go(access.path)):
            await self._take(EVENT_WAIT)
            await self._ok(self.client.pause(access.path))
        await self._write(access)
        if set_up:
            await self._ok(self.client.stop(access.path))

    async def _stream(self, access: AccessNode) -> None:
        """Step 6: SETUP, GO, 1.5 s, PAUSE, 0.25 s, GO, 0.5 s, STOP. While it plays the client beats
        at once and every second (`HEARTBEAT_EVERY`), answers FLOW (its endpoint does), and
        sends `_echo` at the write interval in force."""
        readable, writable = access.readable(), access.writable()
        mode = "both" if readable and writable else "read" if readable else "write"
        if not (readable or writable) or (writable and not self.acquired):
            return
        if not await self._ok(self.client.setup(access.path, mode)):
            return
        if writable:
            self.client.write_values(access.path, lambda: self._echo(access))
        if await self._ok(self.client.go(access.path)):
            await self._take(PLAY)
            await self._ok(self.client.pause(access.path))
            await self._take(PAUSED)
            if await self._ok(self.client.go(access.path)):
                await self._take(REPLAY)
        await self._ok(self.client.stop(access.path))

    def _echo(self, access: AccessNode) -> dict[str, Value]:
        """A DATA payload: per writable node the newest value applied (D-RCTP-20, D-RCTP-21) of
        the readable node of its name, else its zero value."""
        newest = self.client.session.received.get(access.path, {})
        return {node.name: newest.get(node.name, node.zero()) for node in access.writable()}

    async def _clock(self, model: RcmlDocument) -> None:
        """Step 7: the robot's clock minus ours and the uncertainty (D-RCTP-24), when the robot
        has a normal access `clock` to write them to and step 6's heartbeats gave an estimate."""
        clock = next((a for a in _accesses(model, AccessType.NORMAL) if a.name == "clock"), None)
        estimate = self.client.clock
        if clock is None or estimate is None or not self.acquired:
            return
        nodes = {n.name: n for n in clock.writable() if n.type == _FLOAT64}
        if "offset" in nodes and "uncertainty" in nodes:
            for name, value in (("offset", estimate.offset), ("uncertainty", estimate.uncertainty)):
                await self._ok(self.client.write(nodes[name].path, {name: value}))

    # -- requests, and the server's ----------------------------------------------------------

    async def _ok(self, request: Awaitable[object]) -> bool:
        ok, _ = await self._ask(request)
        return ok

    async def _ask(self, request: Awaitable[T]) -> tuple[bool, T | None]:
        """Whether a request was answered 200, and its result. After a refusal the run goes on;
        no answer within the timeout, or the session's end, ends it."""
        try:
            result = await request
        except RctpError as exc:
            if exc.response is None:
                await self._over(str(exc))
            self.refused.append(str(exc))
            await self._drain()
            return False, None
        await self._drain()
        return True, result

    async def _over(self, problem: str) -> NoReturn:
        closed = self.client.closed
        if closed is None:
            raise _Ended(Ending.NO_ANSWER, problem)
        await self._drain()  # the server's BYE, if it sent one, is among the events left
        raise _Ended(Ending.CLOSED, closed.reason)

    async def _drain(self) -> None:
        while (event := await self.client.next_event(0)) is not None:
            self._heard(event)

    async def _take(self, seconds: float) -> None:
        """The server's requests and the stream's values for `seconds`."""
        client = self.client
        deadline = client.loop.time() + seconds
        while (left := deadline - client.loop.time()) > 0:
            event = await client.next_event(left)
            if event is not None:
                self._heard(event)
            elif client.closed is not None:
                await self._over(client.closed.reason)

    def _heard(self, event: ClientEvent) -> None:
        """What the server's requests, already answered by the session (D-RCTP-12), mean here."""
        if isinstance(event, ServerRequest):
            if event.method == "WRITE" and event.status == 200 and event.values is not None:
                for name, value in event.values.items():  # a data-change WRITE (step 5)
                    self.values[f"{event.path}/{name}"] = value
            elif event.method == "STOP" and event.path == self.playing:
                raise _Stopped
            elif event.method == "BYE":
                raise _Ended(Ending.BYE, f"BYE, Reason: {event.reason}" if event.reason else "BYE")
        elif isinstance(event, Closed):
            raise _Ended(Ending.CLOSED, event.reason)


def _accesses(model: RcmlDocument, kind: AccessType) -> list[AccessNode]:
    """The accesses of `kind`, in document order."""
    return [access for access in model.access_nodes() if access.type is kind]


def _nodes(model: RcmlDocument, permission: Permission) -> list[DataNode]:
    """The data nodes of normal accesses that allow `permission`, in document order."""
    return [
        node
        for node in model.data_nodes()
        if permission in node.permission
        and isinstance(access := model.node(node.path.rsplit("/", 1)[0]), AccessNode)
        and access.type is AccessType.NORMAL
    ]
