"""The reference RCTP/2.0 client on asyncio: `ClientSession` with sockets, a clock and awaitables.

    client = await Client.connect("rctp://127.0.0.1:7330/camera", model)
    print(await client.read("/status/lens"))
    await client.acquire("/stream")
    await client.setup("/stream/control", mode="both")
    client.write_values("/stream/control", {"pan": 10, "tilt": 0, "zoom": 50, "focus": 50})
    await client.go("/stream/control")
    event = await client.next_event(timeout=1.0)   # StreamValues, ServerRequest, ...
    await client.close()                           # BYE, then the connection closes

Requests raise `RctpError` for an error status (`check=False` returns the response instead).
Events the application does not take wait in a bounded queue: when it is full the oldest stream
values go first, since the newest are the state (D-RCTP-20).
"""

from __future__ import annotations

import asyncio
import contextlib
import os
import socket
import time
from collections import deque
from collections.abc import Iterable, Mapping
from typing import Self

from rcmlconf import __version__
from rcmlconf.errors import RcmlconfError, ValueTextError
from rcmlconf.rcml.model import AccessNode, AccessType, DataNode, RcmlDocument
from rcmlconf.rcml.url import RctpUrl, parse_rctp_url
from rcmlconf.rctp.bodies import ValuesCodec
from rcmlconf.rctp.datastream.clock import ClockEstimate
from rcmlconf.rctp.datastream.endpoint import HEARTBEAT_EVERY, Address
from rcmlconf.rctp.fields import Transport, format_nodes, parse_nodes
from rcmlconf.rctp.messages import Request, Response
from rcmlconf.rctp.targets import parse_target
from rcmlconf.reference.client.session import (
    Answered,
    ClientEvent,
    ClientSession,
    ClockEstimated,
    Closed,
    StreamValues,
    WriteSource,
)
from rcmlconf.reference.timers import LoopTimer
from rcmlconf.values import Value

USER_AGENT = f"rcmlconf/{__version__}"
#: Events kept for the application at most (D-RCTP-20: old stream values are dropped first).
MAX_EVENTS = 1024


class RctpError(RcmlconfError):
    """A request answered with an error status, or not answered at all."""

    def __init__(self, message: str, response: Response | None = None) -> None:
        super().__init__(message)
        self.response = response

    @classmethod
    def of(cls, request: Request, response: Response) -> RctpError:
        """An error response, with its text body (D-RCTP-8: error responses may explain)."""
        answer = f"{request.method} {request.target}: {response.status} {response.reason}"
        text = response.body.decode("utf-8", "replace").strip()
        if text and (response.headers.get("Content-Type") or "").lower().startswith("text/"):
            answer += f": {text}"
        return cls(answer, response)


class _Control(asyncio.Protocol):
    def __init__(self, client: Client) -> None:
        self.client = client

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        """The client writes on the transport from now on: the server may answer, or close,
        before `create_connection` returns. asyncio has set TCP_NODELAY on its socket (each
        request goes out at once) before anything could close it."""
        assert isinstance(transport, asyncio.Transport)
        self.client._transport = transport

    def data_received(self, data: bytes) -> None:
        self.client._feed(data)

    def eof_received(self) -> bool:
        self.client._feed(b"")
        return False

    def connection_lost(self, exc: Exception | None) -> None:
        self.client._feed(b"")


class _Data(asyncio.DatagramProtocol):
    def __init__(self, client: Client) -> None:
        self.client = client

    def datagram_received(self, data: bytes, addr: Address) -> None:
        self.client._datagram(data, addr)


class Client:
    def __init__(
        self,
        url: RctpUrl,
        session: ClientSession,
        loop: asyncio.AbstractEventLoop,
        timeout: float = 5.0,
    ) -> None:
        self.url = url
        #: Seconds a request waits for its answer unless told otherwise.
        self.timeout = timeout
        self.session = session
        self.loop = loop
        self.model = session.model
        self._transport: asyncio.Transport | None = None
        self._udp: asyncio.DatagramTransport | None = None
        self._timer = LoopTimer(loop, self._timer_fired)
        self._waiting: dict[int, asyncio.Future[Answered]] = {}
        self._events: deque[ClientEvent] = deque()
        self._event_ready = asyncio.Event()
        self.clock: ClockEstimate | None = None
        self.closed: Closed | None = None

    # -- opening and closing -----------------------------------------------------------------

    @classmethod
    async def connect(
        cls,
        url: str | RctpUrl,
        model: RcmlDocument | None = None,
        *,
        timeout: float = 5.0,
        heartbeat_every: float = HEARTBEAT_EVERY,
    ) -> Self:
        """Open the control connection and the session (CONNECT). `timeout` bounds the wait for
        the connection and for each answer; `heartbeat_every` is the seconds between heartbeats
        while a stream plays (D-RCTP-24)."""
        parsed = parse_rctp_url(url) if isinstance(url, str) else url
        try:  # the URL's path is percent-encoded; `request` takes it decoded (D-RCTP-3, D-RCTP-7)
            site = parse_target(parsed.path).path
        except ValueTextError as exc:
            raise RctpError(f"{parsed}: the path is not a site path: {exc}") from None
        loop = asyncio.get_running_loop()
        session = ClientSession(
            model,
            parsed.host,
            loop.time(),
            unix_offset=time.time() - loop.time(),
            first_sequence=int.from_bytes(os.urandom(2), "big"),  # R-RCTP-41
            heartbeat_every=heartbeat_every,
        )
        client = cls(parsed, session, loop, timeout)
        port = parsed.port_or_default
        try:
            await asyncio.wait_for(
                loop.create_connection(lambda: _Control(client), parsed.host, port), timeout
            )
        except (OSError, TimeoutError) as exc:
            client._abort()  # a connection made as the wait ran out is not left open
            raise RctpError(
                f"cannot connect to {parsed.host}:{port}: {exc or 'timed out'}"
            ) from None
        try:
            await client.request("CONNECT", site, [("User-Agent", USER_AGENT)], timeout=timeout)
        except BaseException:
            client._abort()
            raise
        return client

    async def close(self, timeout: float = 5.0) -> None:
        """BYE, then close (R-RCTP-23: the side that sends BYE closes once it is answered).
        The connection closes even when the wait for the answer is cancelled."""
        try:
            if self.closed is None and self.session.conn.session is not None:
                with contextlib.suppress(RctpError):  # closing anyway
                    await self.request("BYE", "*", timeout=timeout, check=False)
        finally:
            self._abort()

    async def __aenter__(self) -> Self:
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.close()

    def _abort(self) -> None:
        if self._transport is not None:
            self._transport.close()
        if self._udp is not None:
            self._udp.close()
        self._timer.set(None)
        # Why the session closed, where it says (the server broke the protocol, ended it), is
        # what a request still waiting is told.
        self._fail_waiting(self.closed.reason if self.closed else "the connection is closed")

    # -- requests ----------------------------------------------------------------------------

    async def request(
        self,
        method: str,
        path: str,
        headers: Iterable[tuple[str, str]] = (),
        body: bytes = b"",
        *,
        timeout: float | None = None,
        check: bool = True,
    ) -> Response:
        """Send a request and wait for its response (`timeout`, else the client's); an error
        status raises unless `check` is False."""
        if timeout is None:
            timeout = self.timeout
        if self.closed is not None:
            raise RctpError(f"{method} {path}: not sent: {self.closed.reason}")
        request = self.session.send(method, path, headers, body, now=self.loop.time())
        future: asyncio.Future[Answered] = self.loop.create_future()
        self._waiting[id(request)] = future
        self._flush()
        try:
            answered = await asyncio.wait_for(future, timeout)
        except TimeoutError:
            raise RctpError(f"{method} {path}: no answer within {timeout:g} s") from None
        except RctpError as exc:  # the session closed first: `_fail_waiting` says why
            raise RctpError(f"{method} {path}: no answer: {exc}") from None
        finally:
            self._waiting.pop(id(request), None)
        response = answered.response
        if check and response.status != 200:
            raise RctpError.of(request, response)
        if check and answered.problem:  # a success the session could not use
            raise RctpError(f"{method} {path}: {answered.problem}", response)
        return response

    def _node(self, path: str) -> DataNode | AccessNode:
        node = self.model.node(path) if self.model is not None else None
        if not isinstance(node, DataNode | AccessNode):
            raise RctpError(f"{path} is not a data or access node of the robot's RCML")
        return node

    def _event_access_of(self, node: DataNode) -> AccessNode | None:
        """The event access a data node belongs to, which READ and WRITE target instead
        (D-RCTP-17, D-RCTP-26); None for a node of a normal access."""
        access = self._node(node.path.rsplit("/", 1)[0])
        assert isinstance(access, AccessNode)  # data lives in access nodes (D-RCML-2)
        return access if access.type is AccessType.EVENT else None

    async def read(self, path: str, nodes: Iterable[str] | None = None) -> dict[str, Value]:
        """The values of a data node, or of an event access's nodes (`nodes`, or every readable
        one), by name (D-RCTP-17). A data node of an event access is read through its access."""
        node = self._node(path)
        if isinstance(node, DataNode):
            access = self._event_access_of(node)
            if access is not None:
                return await self.read(access.path, [node.name])
        headers = [("Nodes", format_nodes(list(nodes)))] if nodes is not None else []
        response = await self.request("READ", path, headers)
        if isinstance(node, DataNode):
            listed: tuple[DataNode, ...] = (node,)
        else:
            try:
                names = parse_nodes(response.headers.get("Nodes") or "")
            except ValueTextError as exc:
                raise RctpError(f"READ {path}: the answer's Nodes: {exc}", response) from None
            by_name = {n.name: n for n in node.data}
            listed = tuple(by_name[n] for n in names if n in by_name)
        try:
            return ValuesCodec(listed, path, "R-RCTP-28").decode(response.body)
        except RcmlconfError as exc:
            raise RctpError(f"READ {path}: the answer's body: {exc}", response) from None

    async def write(self, path: str, values: Mapping[str, Value]) -> None:
        """WRITE a data node ({name: value}), or several nodes of an event access at once
        (D-RCTP-17). A data node of an event access is written through its access."""
        node = self._node(path)
        if isinstance(node, DataNode):
            access = self._event_access_of(node)
            if access is not None:
                return await self.write(access.path, values)
            nodes: list[DataNode] = [node]
            headers = []
        else:
            by_name = {n.name: n for n in node.data}
            unknown = sorted(set(values) - by_name.keys())
            if unknown:
                raise RctpError(f"{path} has no data node {unknown[0]}")
            nodes = [by_name[name] for name in values]
            headers = [("Nodes", format_nodes(list(values)))]
        body = ValuesCodec(nodes, path, "R-RCTP-28").encode(values)
        await self.request("WRITE", path, headers, body)
        return None

    async def acquire(self, path: str) -> None:
        await self.request("ACQUIRE", path)

    async def release(self, path: str = "*") -> None:
        await self.request("RELEASE", path)

    async def setup(self, path: str, mode: str = "read") -> None:
        """SETUP of an event access, or of a stream access with `mode` (D-RCTP-18)."""
        node = self._node(path)
        headers = []
        if isinstance(node, AccessNode) and node.type is AccessType.STREAM:
            port = await self._data_port()
            headers = [("Transport", str(Transport(client_port=port, mode=mode)))]
        await self.request("SETUP", path, headers)

    async def go(self, path: str) -> None:
        await self.request("GO", path)

    async def pause(self, path: str) -> None:
        await self.request("PAUSE", path)

    async def stop(self, path: str) -> None:
        await self.request("STOP", path)

    def write_values(self, path: str, values: WriteSource) -> None:
        """The values a stream writes every interval from now on (held, D-RCTP-20), or a
        function that gives them each interval (`ClientSession.write_values`)."""
        self.session.write_values(path, values)
        self._flush()

    async def _data_port(self) -> int:
        if self._udp is None:
            family = socket.AF_INET6 if ":" in self.url.host else socket.AF_INET
            bind = "::" if family == socket.AF_INET6 else "0.0.0.0"
            self._udp, _ = await self.loop.create_datagram_endpoint(
                lambda: _Data(self), local_addr=(bind, 0), family=family
            )
        return int(self._udp.get_extra_info("sockname")[1])

    # -- events ------------------------------------------------------------------------------

    async def next_event(self, timeout: float | None = None) -> ClientEvent | None:
        """The next server request, stream values, lost stream or clock estimate; None when
        `timeout` passes first or the session is over and nothing is left."""
        deadline = None if timeout is None else self.loop.time() + timeout
        while not self._events:
            if self.closed is not None:
                return None
            self._event_ready.clear()
            left = None if deadline is None else deadline - self.loop.time()
            if left is not None and left <= 0:
                return None
            try:
                await asyncio.wait_for(self._event_ready.wait(), left)
            except TimeoutError:
                return None
        return self._events.popleft()

    def _keep(self, event: ClientEvent) -> None:
        if len(self._events) >= MAX_EVENTS:
            oldest = next((e for e in self._events if isinstance(e, StreamValues)), None)
            if oldest is None:
                return
            self._events.remove(oldest)
        self._events.append(event)
        self._event_ready.set()

    # -- moving bytes ------------------------------------------------------------------------

    def _feed(self, data: bytes) -> None:
        self.session.receive_data(data, self.loop.time())
        self._flush()

    def _datagram(self, data: bytes, addr: Address) -> None:
        self.session.receive_datagram(data, (str(addr[0]), int(addr[1])), self.loop.time())
        self._flush()

    def _timer_fired(self) -> None:
        self.session.handle_timer(self.loop.time())
        self._flush()

    def _flush(self) -> None:
        session = self.session
        while (event := session.next_event()) is not None:
            if isinstance(event, Answered):
                future = self._waiting.get(id(event.request))
                if future is not None and not future.done():
                    future.set_result(event)
            elif isinstance(event, Closed):
                self.closed = event
                self._keep(event)
            else:
                if isinstance(event, ClockEstimated):
                    self.clock = event.estimate
                self._keep(event)
        data = session.data_to_send()
        if data and self._transport is not None and not self._transport.is_closing():
            self._transport.write(data)
        datagrams, peer = session.datagrams_to_send(self.loop.time())
        if datagrams and peer is not None and self._udp is not None:
            for datagram in datagrams:
                self._udp.sendto(datagram, peer)
        self._timer.set(session.get_timer())
        if self.closed is not None:
            self._abort()

    def _fail_waiting(self, reason: str) -> None:
        for future in self._waiting.values():
            if not future.done():
                future.set_exception(RctpError(reason))
