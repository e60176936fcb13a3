"""An RCTP/2.0 control connection as a case drives it: bytes sent exactly as given (a case may
break the grammar on purpose), messages read back whole with the core's `MessageReader`."""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import Sequence

from rcmlconf.conformance.probes.lost import RESET, Contact, by_target, named, network, unreached
from rcmlconf.conformance.probes.outstanding import Outstanding
from rcmlconf.conformance.transcript import Address, Transcript
from rcmlconf.conformance.verdicts import Failed
from rcmlconf.errors import ValueTextError
from rcmlconf.rctp.errors import RemoteProtocolError
from rcmlconf.rctp.fields import parse_nodes
from rcmlconf.rctp.messages import Message, Request, Response
from rcmlconf.rctp.reader import MessageReader
from rcmlconf.rctp.states import Role
from rcmlconf.rctp.targets import parse_target

#: R-RCTP-1: a reply the core's parser rejects without naming a rule breaks the grammar.
GRAMMAR = "R-RCTP-1"
Fields = Sequence[tuple[str, str]]
#: What `response` found when the peer closed the connection instead of answering.
CLOSED = "the connection closed without one"


class ControlProbe:
    def __init__(
        self,
        reader: asyncio.StreamReader,
        writer: asyncio.StreamWriter | None,
        transcript: Transcript,
        wait: float,
        peer: Address | None = None,
    ) -> None:
        """`writer` None: the target reset the connection as it was made (`open`). `peer`: the
        address connected to, where the socket no longer knows it (a reset)."""
        self._reader, self._writer = reader, writer
        self.transcript = transcript
        #: Seconds to wait for an answer (the case's timeout scale applied).
        self.wait = wait
        self._messages = MessageReader()
        self._eof = writer is None
        #: "open", "closed" or "reset" (D-RCTP-1); and the bytes the peer sent (`lost.Contact`).
        self.end = "open" if writer is not None else "reset"
        self.heard = 0
        self.cseq = 0
        #: The session ID once a CONNECT opened one (`Session` is then sent on every request).
        self.session: str | None = None
        # Read now, before any await: a reset takes the peer's name from the socket.
        extra = writer.get_extra_info if writer is not None else lambda _: None
        self.peer = named(extra("peername"), peer or ("0.0.0.0", 0))
        self.local = named(extra("sockname"), ("::" if ":" in self.peer[0] else "0.0.0.0", 0))
        #: `c1`, `c2`, ...: which connection of the case a transcript line is about.
        self.name = transcript.label("c")
        #: How the probe answers the peer's own requests that come while it waits for an answer
        #: (D-RCTP-6 lets either side send requests between answers): a server's WRITE, STOP or
        #: BYE 200, as a client must (R-RCTP-24), once a session is open (before, 454:
        #: `Outstanding.idle_refusal`); `serving` sets how a client's are answered.
        self.own_requests: tuple[int, str] = (200, "OK")
        #: The probe's requests waiting for their answers, which every response read is matched to.
        self.outstanding = Outstanding()

    def serving(self) -> ControlProbe:
        """This probe plays the server of a client under test: the client's own requests that
        come while a case waits for an answer are answered 503, as a server whose robot cannot
        be reached now (D-RCTP-15); the case's own exchange goes on."""
        self.own_requests = (503, "Service Unavailable")
        self.outstanding.side = Role.SERVER
        return self

    @classmethod
    async def open(
        cls, address: Address, transcript: Transcript, wait: float, contact: Contact | None = None
    ) -> ControlProbe:
        """A connection to `address`; an error if it cannot be made. One the target resets as
        it is made is made (D-RCTP-1): the probe reads it as ended. `contact` hears of it."""
        contact = contact or Contact()
        writer: asyncio.StreamWriter | None = None
        try:
            reader, writer = await asyncio.wait_for(asyncio.open_connection(*address), wait)
        except OSError as error:  # TimeoutError too
            if not by_target(error):
                contact.failed(error)
                raise unreached(address, error) from None
            reader = asyncio.StreamReader()
            reader.feed_eof()
        probe = cls(reader, writer, transcript, wait, address)
        contact.made.append(probe)
        transcript.note(f"{probe.name} connected to {address[0]}:{address[1]}")
        if writer is None:
            transcript.note(f"{probe.name} <- the peer reset the connection")
        return probe

    # -- sending -------------------------------------------------------------------------------

    async def send(self, data: bytes, what: str = "") -> None:
        """`data` exactly as given (one write, one TCP segment as far as the kernel lets it)."""
        if self._writer is None:
            return  # reset as it was made: nothing goes out
        self.transcript.sent(f"{self.name} {what}".rstrip(), data)
        self.transcript.packet("tcp", self.local, self.peer, data)
        self.outstanding.sent(data)
        try:
            self._writer.write(data)
            await self._writer.drain()
        except (ConnectionError, OSError) as error:
            self.transcript.note(f"{self.name} send failed: {error}")

    def request_bytes(
        self,
        method: str,
        target: str,
        fields: Fields = (),
        body: bytes = b"",
        *,
        cseq: int | None = None,
    ) -> bytes:
        """A well-formed request with the next CSeq (or `cseq`) and the session, if open."""
        if cseq is None:
            self.cseq += 1
            cseq = self.cseq
        self._note_used(method, target, fields)
        lines = [f"{method} {target} RCTP/2.0", f"CSeq: {cseq}"]
        names = {name.lower() for name, _ in fields}
        if self.session is not None and "session" not in names:
            lines.append(f"Session: {self.session}")
        lines += [f"{name}: {value}" for name, value in fields]
        if body:
            if "content-type" not in names:
                lines.append("Content-Type: application/rctp-values")
            lines.append(f"Content-Length: {len(body)}")
        return ("\r\n".join(lines) + "\r\n\r\n").encode() + body

    def _note_used(self, method: str, target: str, fields: Fields) -> None:
        """The node a request names, and the nodes its `Nodes` lists, for the transcript's
        `used` (a request broken on purpose names none)."""
        if method == "CONNECT":
            return
        try:
            path = parse_target(target).path
        except ValueTextError:
            return
        if path in ("/", "*"):
            return
        listed = next((value for name, value in fields if name.lower() == "nodes"), None)
        try:
            names = parse_nodes(listed) if listed is not None else ()
        except ValueTextError:
            names = ()
        self.transcript.uses(*(f"{path}/{name}" for name in names) if names else (path,))

    async def request(
        self, method: str, target: str, fields: Fields = (), body: bytes = b""
    ) -> Response:
        """Send a well-formed request and return its answer (R-RCTP-5: the next response)."""
        await self.send(self.request_bytes(method, target, fields, body))
        return await self.response()

    async def answer(
        self, request: Request, status: int = 200, reason: str = "OK", fields: Fields = ()
    ) -> None:
        """Answer one of the target's requests (R-RCTP-24), with its CSeq and the session."""
        await self.send(self.response_bytes(request, status, reason, fields))

    def response_bytes(
        self,
        request: Request,
        status: int = 200,
        reason: str = "OK",
        fields: Fields = (),
        body: bytes = b"",
    ) -> bytes:
        """An answer to `request` with its CSeq, the session if open, and `body` (framed by
        Content-Length; `fields` give its Content-Type)."""
        lines = [f"RCTP/2.0 {status} {reason}", f"CSeq: {request.headers.get('CSeq')}"]
        names = {name.lower() for name, _ in fields}
        if self.session is not None and "session" not in names:
            lines.append(f"Session: {self.session}")
        lines += [f"{name}: {value}" for name, value in fields]
        if body:
            lines.append(f"Content-Length: {len(body)}")
        return ("\r\n".join(lines) + "\r\n\r\n").encode() + body

    # -- receiving -----------------------------------------------------------------------------

    def already_read(self, data: bytes) -> None:
        """Bytes of the peer's read before the probe had the connection (the client role reads
        a first request's head to know its case): read first, as if they came now."""
        if data:
            self.heard += len(data)
            self.transcript.packet("tcp", self.peer, self.local, data)
            self._messages.feed(data)

    async def message(
        self, wait: float | None = None, cseq_rule: str | None = None
    ) -> Message | None:
        """The next whole message; None if the target closed the connection first. Waiting
        longer than `wait` (the probe's by default) is a failure of R-RCTP-5. A response must
        answer the oldest request waiting (`Outstanding.answered`; `cseq_rule`: the requirement
        a case judges its CSeq under)."""
        deadline = asyncio.get_running_loop().time() + (self.wait if wait is None else wait)
        while True:
            try:
                found = self._messages.next_message()
            except RemoteProtocolError as error:
                raise Failed(
                    error.rule or GRAMMAR,
                    "a message of RCTP/2.0's grammar",
                    f"{error.reason} at byte {error.offset} of the target's stream",
                ) from None
            if found is not None:
                self._record(found)
                if isinstance(found, Response):
                    self.outstanding.answered(found, cseq_rule)
                return found
            if self._eof:
                return None
            remaining = deadline - asyncio.get_running_loop().time()
            try:
                data = await asyncio.wait_for(self._reader.read(65536), max(remaining, 0))
            except TimeoutError:
                raise Failed(
                    "R-RCTP-5",
                    "an answer",
                    f"nothing within {self.wait if wait is None else wait:g} s",
                ) from None
            except OSError as error:
                if not by_target(error):
                    raise network(error, self.name) from None
                self.end = "reset"
                data = b""
            if not data:
                self._eof = True
                if self.end == "open":
                    self.end = "closed"
                self.transcript.note(f"{self.name} <- the peer {self.end} the connection")
                continue
            self.heard += len(data)
            self.transcript.packet("tcp", self.peer, self.local, data)
            self._messages.feed(data)

    async def response(
        self, wait: float | None = None, closed: str = "R-RCTP-5", cseq_rule: str | None = None
    ) -> Response:
        """The next message, which must be a response (to the oldest request waiting, as
        `message` says): the target's own requests in between are answered (`own_requests`;
        before a session, refused as D-RCTP-13 says) and skipped, as D-RCTP-6 allows them. A
        connection closed first breaks `closed`."""
        for _ in range(64):
            found = await self.message(wait, cseq_rule)
            if found is None:
                raise Failed(closed, "an answer", RESET if self.end == "reset" else CLOSED)
            if isinstance(found, Response):
                return found
            await self.answer(found, *(self.outstanding.idle_refusal(found) or self.own_requests))
        raise Failed("R-RCTP-5", "an answer", "64 requests of the target's and no answer")

    async def next_request(
        self, wait: float | None = None, requirement: str = "R-RCTP-24"
    ) -> Request:
        """The peer's next message, which must be a request (a client under test speaks
        first)."""
        try:
            found = await self.message(wait)
        except Failed as failed:
            if not waited_out(failed):
                raise
            waited = self.wait if wait is None else wait
            sent = self._messages.offset + self._messages.buffered
            what = "sent no whole request" if sent else "connected and sent nothing"
            within = f"within {waited:.3g} s"
            reason = f"the client {what} {within} (expected a request)"
            raise Failed(requirement, "a request", f"nothing {within}", reason) from None
        if found is None:
            raise Failed(requirement, "a request", "the connection closed")
        if not isinstance(found, Request):
            raise Failed(requirement, "a request", f"a response, {found.status} {found.reason}")
        return found

    async def outcome(self, wait: float) -> str:
        """What the peer does within `wait`: "closed" (nothing sent first), "silent", or what
        it sent."""
        try:
            found = await self.message(max(wait, 0.0))
        except Failed as failed:
            if failed.requirement != "R-RCTP-5" or failed is self.outstanding.failure:
                raise
            return "silent"
        return "closed" if found is None else f"it sent {describe(found)}"

    async def closes(self, wait: float | None = None) -> bool:
        """Whether the target closes the connection within `wait` (messages before are read; an
        answer among them out of place fails, as `message` says)."""
        try:
            for _ in range(64):
                if await self.message(wait) is None:
                    return True
        except Failed as failed:
            if failed is self.outstanding.failure:
                raise
        return self._eof

    async def connect(self, target: str = "/", fields: Fields = ()) -> Response:
        """CONNECT; on 200 the session is kept for the requests that follow."""
        answer = await self.request("CONNECT", target, fields)
        if answer.status == 200:
            self.session = (answer.headers.get("Session") or "").split(";")[0].strip() or None
        return answer

    def close(self) -> None:
        if self._writer is not None:
            with contextlib.suppress(Exception):
                self._writer.close()

    def _record(self, message: Message) -> None:
        if isinstance(message, Request):
            self.transcript.note(
                f"{self.name} <- {message.method} {message.target} {_fields(message)}"
            )
        else:
            self.transcript.note(
                f"{self.name} <- {message.status} {message.reason} {_fields(message)}"
            )


def _fields(message: Message) -> str:
    shown = ", ".join(f"{name}: {value}" for name, value in message.headers)
    return f"[{shown}]" + (f" +{len(message.body)} bytes" if message.body else "")


def describe(message: Message | None) -> str:
    """A message in a few words: `GO /a`, `455 Method Not Valid in This State`."""
    if message is None:
        return "nothing (the connection closed)"
    if isinstance(message, Request):
        return f"{message.method} {message.target}"
    return f"{message.status} {message.reason}"


def waited_out(failed: Failed) -> bool:
    """Whether `message` failed for waiting in vain (R-RCTP-5: nothing within its wait), not
    for another break of R-RCTP-5 it read."""
    return failed.requirement == "R-RCTP-5" and failed.actual.startswith("nothing within")
