"""The robot's files over HTTP/1.1 as a case fetches them (D-RCTP-29): one connection, requests
sent one at a time, answers read whole by h11 and judged by the case. Every read is bounded in
time (the probe's wait) and in size (a document's limit, D-XML-5), and anything the server does
instead of answering (refusing the connection, closing it, breaking HTTP) is a failure of the
requirement the case names, never an error of the harness: a target whose ICS declares `files`
has them to serve.
"""

from __future__ import annotations

import asyncio
from dataclasses import dataclass

import h11

from rcmlconf import __version__
from rcmlconf.conformance.probes.lost import RESET, by_target, named, network, said
from rcmlconf.conformance.transcript import Address, Transcript
from rcmlconf.conformance.verdicts import Failed
from rcmlconf.markup.failure import MAX_DOCUMENT_BYTES

#: The longest head an answer may have (h11 buffers no more of it).
MAX_HEAD = 65536
#: The longest body read: a document's (D-XML-5); the index page is smaller than that too.
MAX_BODY = MAX_DOCUMENT_BYTES
_READ_SIZE = 65536
_AGENT = f"rcmlconf/{__version__} (conformance)"


@dataclass(frozen=True, slots=True)
class Answer:
    status: int
    reason: str
    #: Header fields, names in lower case, in the order sent.
    headers: tuple[tuple[str, str], ...]
    body: bytes
    #: The server closes the connection after this answer (`Connection: close`, RFC 9112 §9.6).
    closing: bool

    def header(self, name: str) -> str | None:
        return next((value for key, value in self.headers if key == name.lower()), None)

    @property
    def media_type(self) -> str:
        """`text/html` of `Content-Type: text/html; charset=utf-8`, in lower case ("" without)."""
        return (self.header("content-type") or "").split(";", 1)[0].strip().lower()

    @property
    def status_line(self) -> str:
        """`200 OK`, or `200` when the reason phrase is empty (RFC 9112 §4 lets it be)."""
        return f"{self.status} {self.reason}".rstrip()

    def __str__(self) -> str:
        length = self.header("content-length")
        told = f"Content-Length {length}" if length is not None else "no Content-Length"
        closing = ", Connection: close" if self.closing else ""
        return f"{self.status_line} ({told}, {len(self.body)} bytes of body{closing})"


class FilesProbe:
    """One HTTP/1.1 connection to the robot's files."""

    def __init__(
        self,
        reader: asyncio.StreamReader,
        writer: asyncio.StreamWriter,
        transcript: Transcript,
        wait: float,
        host: str,
        peer: Address,
    ) -> None:
        """`host`: the Host field's; `peer`: the address connected to."""
        self._reader, self._writer = reader, writer
        self.transcript = transcript
        self.wait = wait
        self._host = host
        self._conn = h11.Connection(h11.CLIENT, max_incomplete_event_size=MAX_HEAD)
        # Read now, before any await: a reset takes the peer's name from the socket.
        self.peer = named(writer.get_extra_info("peername"), peer)
        self.local = named(writer.get_extra_info("sockname"), ("0.0.0.0", 0))
        self.name = transcript.label("h")

    @classmethod
    async def open(
        cls, address: Address, transcript: Transcript, wait: float, requirement: str
    ) -> FilesProbe:
        """A connection to the files at `address`; one that cannot be had breaks `requirement`
        (the ICS says the target serves them there)."""
        host, port = address
        try:
            reader, writer = await asyncio.wait_for(asyncio.open_connection(host, port), wait)
        except OSError as error:  # TimeoutError too
            got = RESET if by_target(error) else f"no connection: {said(error)}"
            raise Failed(
                requirement,
                f"the robot's files on HTTP at {host}:{port}, the port after RCTP's (D-RCTP-29)",
                f"{got} (a server that does not offer its files says so in its ICS: files = false)",
            ) from None
        name = f"[{host}]:{port}" if ":" in host else f"{host}:{port}"
        probe = cls(reader, writer, transcript, wait, name, address)
        transcript.note(f"{probe.name} connected to {name} (the robot's files)")
        return probe

    @property
    def reusable(self) -> bool:
        """Another request may be sent: the last answer kept the connection (RFC 9112 §9.3)."""
        return self._conn.our_state is h11.IDLE and self._conn.their_state is h11.IDLE

    @property
    def unread(self) -> bytes:
        """What the server sent after its last whole answer, read but not yet taken."""
        return bytes(self._conn.trailing_data[0])

    async def ask(
        self, method: str, target: str, requirement: str, *, last: bool = False
    ) -> Answer:
        """Send `method target` and read its whole answer; anything else breaks `requirement`.
        `last`: the request says `Connection: close`, so the server closes the connection after
        its answer (RFC 9112 §9.6) and `closed` reads what it sent up to then."""
        fields = [("Host", self._host), ("User-Agent", _AGENT), ("Accept", "*/*")]
        if method not in ("GET", "HEAD"):  # it sends no content, and says so (RFC 9110 §8.6)
            fields.append(("Content-Length", "0"))
        if last:
            fields.append(("Connection", "close"))
        request = h11.Request(method=method, target=target, headers=fields)
        data = self._conn.send(request) + (self._conn.send(h11.EndOfMessage()) or b"")
        self.transcript.sent(self.name, data)
        self.transcript.packet("tcp", self.local, self.peer, data)
        try:
            self._writer.write(data)
            await self._writer.drain()
        except OSError as error:  # a peer that closed: the read below says so
            self.transcript.note(f"{self.name} send failed: {error}")
        answer = await self._answer(f"{method} {target}", requirement)
        self.transcript.note(f"{self.name} <- {method} {target}: {answer}")
        if self._conn.our_state is h11.DONE and self._conn.their_state is h11.DONE:
            self._conn.start_next_cycle()  # a persistent connection (RFC 9112 §9.3)
        return answer

    async def _answer(self, asked: str, requirement: str) -> Answer:
        response: h11.Response | None = None
        body = bytearray()
        while True:
            event = await self._event(asked, requirement, response is not None)
            if isinstance(event, h11.Response):
                response = event
            elif isinstance(event, h11.Data):
                body += event.data
                if len(body) > MAX_BODY:
                    raise Failed(
                        requirement,
                        f"{asked}: a body of at most {MAX_BODY:,} bytes (a document's, D-XML-5)",
                        f"more than {MAX_BODY:,} bytes",
                    )
            elif isinstance(event, h11.EndOfMessage) and response is not None:
                return Answer(
                    response.status_code,
                    response.reason.decode("latin-1"),
                    tuple(
                        (name.decode("latin-1").lower(), value.decode("latin-1"))
                        for name, value in response.headers
                    ),
                    bytes(body),
                    self._conn.their_state is h11.MUST_CLOSE,
                )
            elif not isinstance(event, h11.InformationalResponse):  # 1xx: the answer follows
                raise Failed(requirement, f"{asked}: an answer", "the connection ended first")

    async def _event(self, asked: str, requirement: str, started: bool) -> h11.Event | type:
        """h11's next event, reading as it needs, each read bounded by the probe's wait."""
        while True:
            try:
                event = self._conn.next_event()
            except h11.RemoteProtocolError as error:
                raise Failed(
                    requirement, f"{asked}: an HTTP/1.1 answer (RFC 9112)", f"{error}"
                ) from None
            if event is not h11.NEED_DATA:
                return event
            reset = False
            try:
                data = await asyncio.wait_for(self._reader.read(_READ_SIZE), self.wait)
            except TimeoutError:
                what = "the rest of the answer" if started else "an answer"
                raise Failed(
                    requirement, f"{asked}: an answer", f"{what} not within {self.wait:g} s"
                ) from None
            except OSError as error:
                data, reset = self._lost(error), True
            if data:
                self.transcript.packet("tcp", self.peer, self.local, data)
            else:
                how = "reset" if reset else "closed"
                self.transcript.note(f"{self.name} <- the server {how} the connection")
                if not started:  # h11 would call it a protocol error; it is no answer
                    got = RESET if reset else "the connection closed without one"
                    raise Failed(requirement, f"{asked}: an answer", got)
            self._conn.receive_data(data)

    async def closed(self, wait: float) -> tuple[bytes, bool]:
        """After the last answer the connection carries (`Answer.closing`): what the server
        sends after it, and whether it then closed the connection (RFC 9112 §9.6 has it close),
        read for `wait` seconds at most."""
        extra = self.unread
        loop = asyncio.get_running_loop()
        deadline = loop.time() + wait
        while len(extra) <= MAX_BODY:
            try:
                data = await asyncio.wait_for(
                    self._reader.read(_READ_SIZE), max(deadline - loop.time(), 0)
                )
            except TimeoutError:
                return extra, False
            except OSError as error:
                data = self._lost(error)
            if not data:
                self.transcript.note(f"{self.name} <- the server closed the connection")
                return extra, True
            self.transcript.packet("tcp", self.peer, self.local, data)
            extra += data
        return extra, False

    def _lost(self, error: OSError) -> bytes:
        """What a read that failed with `error` read: nothing, once the server reset the
        connection (D-RCTP-1); any other failure is the network's, an error."""
        if not by_target(error):
            raise network(error, self.name)
        return b""

    def close(self) -> None:
        self._writer.close()
