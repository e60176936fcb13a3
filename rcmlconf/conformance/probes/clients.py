"""Where RCTP/2.0 clients under test connect (`--role client --listen PORT`): the harness plays
the server of its robot, as Autobahn's fuzzing server does, and each client case is one run of
D-RCTP-31's scenario.

Each case has its own URL, `rctp://HOST:PORT/<case id>`, and its own files at
`http://HOST:PORT+1/<case id>/` (D-RCTP-29 with the case's path): the robot's RCML, whose `site` is
the case's URL, and whatever else the case serves. `/cases` lists the URLs in the order the cases
run, for a client that loops over them itself. The embedded reference has a `summon` that starts
one reference client on the case's URL whenever a case waits for a connection; `--client-command`
one process (`command.Command`).

Whose each connection is (D-RCTP-31, `_route`): the case whose started process holds its other
end, when `owners` can tell (`owners.Owners`), so a client that breaks the grammar, CONNECTs
elsewhere or sends nothing is judged by its own case, beside the others; else the case its
CONNECT names, so a late client never lands in the next case; else a running case still waiting
for its first connection (the one that began first), or the one case running, or, when the
harness starts no client, the next case to run; else nobody's: it is closed. Each case keeps
MAX_WAITING connections waiting, so a flood from one case's client closes only its own.
"""

from __future__ import annotations

import asyncio
import contextlib
import re
from collections import Counter
from collections.abc import Awaitable, Callable, Mapping, Sequence
from pathlib import Path
from typing import cast
from urllib.parse import quote, unquote, urlsplit

from rcmlconf.conformance.owners import Owners
from rcmlconf.conformance.probes.control import ControlProbe
from rcmlconf.conformance.transcript import Address, Transcript
from rcmlconf.conformance.verdicts import Inconclusive
from rcmlconf.rcml.model import RcmlDocument
from rcmlconf.rcml.url import http_base
from rcmlconf.reference.server.files import INDEX_TYPE, XML_TYPE, Document, FileServer, index_page

Summon = Callable[[str], Awaitable[None]]
#: A client case's RCML from its robot's RCML and the case's files URL (`registry.Case.served`):
#: what the played server's files serve that case.
Served = Callable[[bytes, str], bytes]

#: The robot the harness plays to clients (D-RCTP-31's last paragraph).
HARNESS_RCML = Path(__file__).resolve().parent.parent / "robot" / "harness.rcml"
#: D-RCTP-31: the case URLs, one per line, in the order the cases run.
CASE_LIST = "/cases"
#: The name of the robot's RCML among a case's files.
RCML_NAME = "harness.rcml"
#: How long a connection whose owner is unknown has to send the head of its first request
#: before it is given to a case unread (D-RCTP-31): one that sends nothing is that case's to
#: judge.
FIRST_REQUEST_WAIT = 2.0
#: The head of a first request, at most (D-RCTP-9's header section).
MAX_HEAD = 16384
#: D-RCTP-31: connections waiting for their case, at most, each case; more are closed.
MAX_WAITING = 16
#: D-RCTP-31: connections (and file requests) waiting for cases not yet reached, at most in all.
MAX_EARLY = 16
#: D-RCTP-31: connections whose first head is being read, at most at once.
MAX_READING = 64
#: Connections the kernel holds for the listener to accept: room for a client's burst, so that
#: its connects are not dropped and retried a second later (asyncio's default is 100).
BACKLOG = 1024
#: How long a file request for a case not yet reached waits for it.
FILES_WAIT = 60.0
_HEAD_END = re.compile(rb"\n\r?\n")
_SITE = re.compile(rb"""\bsite\s*=\s*("[^"]*"|'[^']*')""")

_Accepted = tuple[asyncio.StreamReader, asyncio.StreamWriter, bytes]


def case_path(case_id: str) -> str:
    """The path of a case's URL (D-RCTP-31): `/` and the case's ID, percent-encoded."""
    return "/" + quote(case_id, safe="/")


class ClientListener:
    def __init__(
        self,
        robot: RcmlDocument,
        rcml: bytes,
        summon: Summon | None = None,
        stop: Callable[[str], list[str]] | None = None,
        on_wait: Callable[[str], None] | None = None,
        owners: Owners | None = None,
    ) -> None:
        #: The robot the harness plays, and its RCML as written: each case's copy names the
        #: case's URL as `site`.
        self.robot = robot
        self._rcml = rcml
        #: Starts a client on a case's URL (the embedded reference, --client-command); `stop`
        #: stops the one of a URL when its case ends, and says how it ran, for the report.
        self._summon = summon
        self._stop = stop
        #: Told of each case that waits for a client it does not start itself (the CLI's line).
        self._on_wait = on_wait
        #: Which started client holds a connection's other end, by the URL it was started on.
        self._owners = owners
        self._arrived: dict[str, asyncio.Event] = {}
        self._summoned: dict[str, asyncio.Future[None]] = {}
        self._ever_connected = False
        self._given_up = False
        self._server: asyncio.Server | None = None
        self._files: asyncio.Server | None = None
        self._planned: Counter[str] = Counter()
        #: The runs of client cases planned (`plan`).
        self.runs = 0
        self._order: list[str] = []
        #: The cases running, in the order they began, and those of them that have had a
        #: connection; of each case, its connections closed past MAX_WAITING.
        self._running: dict[str, None] = {}
        self._connected: set[str] = set()
        self._over: Counter[str] = Counter()
        self._reached: dict[str, asyncio.Event] = {}
        self._queues: dict[str, asyncio.Queue[_Accepted]] = {}
        self._served: dict[str, Served] = {}
        self._fetched: dict[str, list[str]] = {}
        #: The first sequence number of each stream of the client's the played server saw, case
        #: after case: R-RCTP-41's random start shows only over several runs.
        self.stream_starts: list[int] = []
        #: File requests waiting for their case; connections whose first head is being read.
        self._files_waiting = 0
        self._reading = 0
        self._read = asyncio.Event()
        self._tasks: set[asyncio.Task[None]] = set()

    @property
    def starts_clients(self) -> bool:
        """Whether the harness starts a client for each case (so cases may run at once)."""
        return self._summon is not None

    # -- the run's plan ------------------------------------------------------------------------

    def plan(self, case_ids: Sequence[str], served: Mapping[str, Served] | None = None) -> None:
        """The client cases of the run, in the order they run (repeats included), and the RCML
        of those that serve their own (`Case.served`)."""
        self._served = dict(served or {})
        self._order = list(dict.fromkeys(case_ids))
        self._planned = Counter(case_ids)
        self.runs = len(case_ids)
        for case_id in self._order:
            self._reached.setdefault(case_id, asyncio.Event())
            self._queues.setdefault(case_id, asyncio.Queue())

    def url(self, case_id: str) -> str:
        host, port = self.address
        shown = f"[{host}]" if ":" in host else host
        return f"rctp://{shown}:{port}{case_path(case_id)}"

    def files_url(self, case_id: str) -> str:
        host, port = self.address
        return f"{http_base(host, port + 1)}{case_path(case_id)}/"

    def fetched(self, case_id: str) -> list[str]:
        """The paths of the case's files the client asked for, in order."""
        return list(self._fetched.get(case_id, ()))

    def done(self, case_id: str) -> None:
        """The case has ended: its connections still waiting are closed, and once its last run
        has ended a CONNECT that names it is answered 404 (D-RCTP-31)."""
        self._planned[case_id] -= 1
        self._running.pop(case_id, None)
        self._connected.discard(case_id)
        self._over.pop(case_id, None)
        queue = self._queues.get(case_id)
        while queue is not None and not queue.empty():
            _, writer, _ = queue.get_nowait()
            writer.close()
        self._arrived.pop(case_id, None)
        self._summoned.pop(case_id, None)
        if self._planned[case_id] > 0:
            self._reached[case_id] = asyncio.Event()

    # -- sockets -------------------------------------------------------------------------------

    async def start(self, host: str, port: int) -> None:
        """Listen on `port` (RCTP) and the port after it (the files, D-RCTP-29); port 0 picks a
        free pair."""
        for _ in range(20 if port == 0 else 1):
            self._server = await asyncio.start_server(self._accepted, host, port, backlog=BACKLOG)
            rctp_port = self._server.sockets[0].getsockname()[1]
            try:
                files = _CaseFiles(self)
                self._files = await asyncio.start_server(files.handle, host, rctp_port + 1)
                return
            except OSError:
                self._server.close()
                await self._server.wait_closed()
                self._server = None
                if port != 0:
                    raise
        raise OSError("no free pair of ports for the client role's RCTP and files")

    @property
    def address(self) -> Address:
        assert self._server is not None, "start() first"
        host, port = self._server.sockets[0].getsockname()[:2]
        return host, port

    def _accepted(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        self._spawn(self._route(reader, writer))

    def _spawn(self, work: Awaitable[None]) -> asyncio.Future[None]:
        task = asyncio.ensure_future(work)
        self._tasks.add(task)
        task.add_done_callback(self._tasks.discard)
        return task

    async def _route(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        """Give the connection to its case (D-RCTP-31): its owner's, else the one its first
        request names, else one waiting for its first connection; or close it."""
        ours, peer = _address(writer, "sockname"), _address(writer, "peername")
        case_id = self._owned(ours, peer)
        head = b""
        if case_id is None:
            if self._reading >= MAX_READING:
                writer.close()
                return
            self._reading += 1
            self._read.clear()
            try:
                head = await _first_head(reader)
            finally:
                self._reading -= 1
                if not self._reading:
                    self._read.set()
            # The owner again: a client may connect before the harness knows its process.
            case_id = self._owned(ours, peer) or self._named(_connect_target(head))
            if case_id is not None and self._planned[case_id] <= 0:
                writer.write(_not_found(head))  # D-RCTP-31: a case already run
                with contextlib.suppress(OSError):
                    await writer.drain()
                writer.close()
                return
            case_id = case_id or self._unclaimed()
        if case_id is None or self._planned[case_id] <= 0:
            writer.close()
            return
        queue = self._queues[case_id]
        early = not self._reached[case_id].is_set()
        if queue.qsize() >= MAX_WAITING or (early and self._early() >= MAX_EARLY):
            self._over[case_id] += 1
            writer.close()
            return
        self._ever_connected = True
        self._connected.add(case_id)
        queue.put_nowait((reader, writer, head))
        self._arrived.setdefault(case_id, asyncio.Event()).set()

    def _owned(self, ours: Address | None, peer: Address | None) -> str | None:
        """The case whose started client holds the other end of the connection, if known."""
        if self._owners is None or ours is None or peer is None:
            return None
        url = self._owners.owner(ours, peer)
        return None if url is None else self._named(unquote(urlsplit(url).path)[1:])

    def _named(self, case_id: str | None) -> str | None:
        return case_id if case_id in self._reached else None

    def _unclaimed(self) -> str | None:
        """Whose a connection is that nothing else attributes (D-RCTP-31): the running case
        that began first of those without a connection yet, else the one case running, else,
        when the harness starts no client, the next case to run."""
        waiting = (c for c in self._running if c not in self._connected)
        if (first := next(waiting, None)) is not None:
            return first
        if len(self._running) == 1:
            return next(iter(self._running))
        if self._running or self.starts_clients:
            return None
        return next((c for c in self._order if self._planned[c]), None)

    def _early(self) -> int:
        """Connections and file requests waiting for cases not yet reached."""
        queued = (q.qsize() for c, q in self._queues.items() if not self._reached[c].is_set())
        return sum(queued) + self._files_waiting

    async def arrival(self, case_id: str, wait: float) -> str | None:
        """Before the case's clock starts: its first connection, from a client summoned if the
        harness starts them, waited for up to `wait` (--connect-timeout). None once it came;
        else why not. After a case in which no client of the run had ever connected, the rest
        give up at once: a run with no client is an error, not a long wait."""
        queue = self._begin(case_id)
        if not queue.empty():
            return None
        if self._given_up:
            return f"no client has connected to the harness (the first case waited {wait:g} s)"
        if self._on_wait is not None and self._summon is None:
            self._on_wait(case_id)
        arrived: asyncio.Future[object] = asyncio.ensure_future(
            self._arrived.setdefault(case_id, asyncio.Event()).wait()
        )
        summoned = self._summoned.get(case_id)
        either: list[asyncio.Future[object]] = [arrived]
        if summoned is not None:  # a client started for the case that ends unconnected: no wait
            either.append(cast("asyncio.Future[object]", summoned))
        try:
            await asyncio.wait(either, timeout=wait, return_when=asyncio.FIRST_COMPLETED)
            if queue.empty() and self._reading:  # it may be one whose first head is read
                with contextlib.suppress(TimeoutError):
                    await asyncio.wait_for(self._read.wait(), FIRST_REQUEST_WAIT)
        finally:
            arrived.cancel()
        if not queue.empty():
            return None
        self._given_up = not self._ever_connected
        if summoned is not None and summoned.done():
            return f"the client started for {self.url(case_id)} ended before it connected"
        return f"no client connected for {self.url(case_id)} within {wait:g} s"

    def finish(self, case_id: str) -> list[str]:
        """The client started for the case is stopped if it still runs: how it ran, and how
        many of its connections were closed past MAX_WAITING, for the case's report."""
        lines = self._stop(self.url(case_id)) if self._stop is not None else []
        if over := self._over[case_id]:
            lines.append(
                f"{over} more connections of the case's client were closed unread: a case keeps"
                f" {MAX_WAITING} waiting at most (D-RCTP-31)"
            )
        return lines

    def _begin(self, case_id: str) -> asyncio.Queue[_Accepted]:
        """The case runs: its connections are its own, and a client is started for it if the
        harness starts them and none is waiting."""
        self._running.setdefault(case_id, None)
        self._reached.setdefault(case_id, asyncio.Event()).set()
        queue = self._queues.setdefault(case_id, asyncio.Queue())
        if self._summon is not None and queue.empty():
            self._summoned[case_id] = self._spawn(self._summon(self.url(case_id)))
        return queue

    async def accept(self, case_id: str, transcript: Transcript, wait: float) -> ControlProbe:
        """The case's next connection; inconclusive if none comes within `wait`."""
        queue = self._begin(case_id)
        try:
            reader, writer, head = await asyncio.wait_for(queue.get(), wait)
        except TimeoutError:
            if case_id in self._connected:
                why = f"the client opened no other connection for {self.url(case_id)}"
            else:
                why = f"no client connected for {self.url(case_id)}"
            raise Inconclusive(f"{why} within {wait:g} s") from None
        if queue.empty():
            self._arrived.setdefault(case_id, asyncio.Event()).clear()
        probe = ControlProbe(reader, writer, transcript, wait).serving()
        peer = probe.peer
        transcript.note(f"{probe.name} a client connected from {peer[0]}:{peer[1]}")
        probe.already_read(head)
        return probe

    # -- the files -----------------------------------------------------------------------------

    def case_files(self, case_id: str) -> dict[str, bytes]:
        """The case's files by name: the robot's RCML naming the case's URL as its site, or
        the case's own made from it."""
        site = f'site="{self.url(case_id)}"'.encode()
        rcml = _SITE.sub(lambda _: site, self._rcml, count=1)
        if (served := self._served.get(case_id)) is not None:
            rcml = served(rcml, self.files_url(case_id))
        return {RCML_NAME: rcml}

    def case_of(self, path: str) -> str | None:
        """The case whose files `path` names."""
        for case_id in self._order:
            if path.startswith(case_path(case_id) + "/"):
                return case_id
        return None

    async def file(self, path: str) -> tuple[int, bytes, str]:
        """What a GET of `path` on the files port gets."""
        if path == CASE_LIST:
            urls = "".join(f"{self.url(c)}\n" for c in self._order)
            return 200, urls.encode(), "text/plain; charset=utf-8"
        case_id = self.case_of(path)
        if case_id is None:
            return 404, b"no case of this run has files there\n", "text/plain"
        self._fetched.setdefault(case_id, []).append(path)
        reached = self._reached[case_id]
        if not reached.is_set():  # the case's own files are set when it starts: wait for it
            if self._early() >= MAX_EARLY:
                return 503, b"too many requests waiting for their case\n", "text/plain"
            self._files_waiting += 1
            try:
                await asyncio.wait_for(reached.wait(), FILES_WAIT)
            except TimeoutError:
                return 503, b"the case did not start in time\n", "text/plain"
            finally:
                self._files_waiting -= 1
        files = self.case_files(case_id)
        name = unquote(path[len(case_path(case_id)) + 1 :])
        if not name:
            listed = {quote(n): Document(n, data) for n, data in files.items()}
            return 200, index_page(case_id, listed), INDEX_TYPE
        if name in files:
            return 200, files[name], XML_TYPE
        return 404, b"not one of this case's files\n", "text/plain"

    async def close(self) -> None:
        for task in list(self._tasks):
            task.cancel()
        for task in list(self._tasks):
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await task
        for queue in self._queues.values():
            while not queue.empty():
                _, writer, _ = queue.get_nowait()
                writer.close()
        for server in (self._server, self._files):
            if server is not None:
                server.close()
                await server.wait_closed()


class _CaseFiles(FileServer):
    """The files port of the client role: each case's files under its path, and `/cases`."""

    def __init__(self, listener: ClientListener) -> None:
        super().__init__("rcmlconf's client cases", {})
        self._listener = listener

    async def find(self, path: str) -> tuple[int, bytes, str]:
        return await self._listener.file(path)


async def _first_head(reader: asyncio.StreamReader) -> bytes:
    """What the connection sends until the end of its first head (bounded in time and size)."""
    head = b""
    loop = asyncio.get_running_loop()
    deadline = loop.time() + FIRST_REQUEST_WAIT
    # Any blank line ends it: a head with bare LFs is the case's to judge (R-RCTP-1).
    while not _HEAD_END.search(head) and len(head) < MAX_HEAD:
        try:
            data = await asyncio.wait_for(reader.read(MAX_HEAD), deadline - loop.time())
        except (TimeoutError, OSError):
            break
        if not data:
            break
        head += data
    return head


def _address(writer: asyncio.StreamWriter, which: str) -> Address | None:
    """The connection's `sockname` or `peername`; None once it is gone (reset at once)."""
    found = writer.get_extra_info(which)
    return (str(found[0]), int(found[1])) if isinstance(found, tuple) else None


def _connect_target(head: bytes) -> str | None:
    """The case a first request's CONNECT names (its target, percent-decoded, less the `/`)."""
    words = head.split(b"\r\n", 1)[0].split(b" ")
    if len(words) != 3 or words[0] != b"CONNECT" or not words[1].startswith(b"/"):
        return None
    return unquote(words[1].decode("ascii", "replace"))[1:]


def _not_found(head: bytes) -> bytes:
    """404 to a CONNECT of a case already run, with its CSeq (D-RCTP-31)."""
    found = re.search(rb"\r\nCSeq:[ \t]*(\d{1,9})[ \t]*\r\n", head, re.IGNORECASE)
    cseq = found.group(1).decode() if found else "1"
    return f"RCTP/2.0 404 Not Found\r\nCSeq: {cseq}\r\n\r\n".encode()
