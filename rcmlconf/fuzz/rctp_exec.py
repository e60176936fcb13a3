"""One test case against an RCTP/2.0 server, on real sockets: its prefix, its steps, what came
back, and how the connection ended (D-FUZZ-1, D-FUZZ-4).

Blocking sockets and `select`, one connection a case: the fuzzer waits for nothing but the
target, so it runs as fast as the target answers. The fuzzer plays a client as a client must
(R-RCTP-24): the server's own requests (WRITE, STOP, BYE) are answered 200, but for the STOP
that D-FUZZ-2's `stop unanswered` leaves unanswered.
"""

from __future__ import annotations

import contextlib
import select
import socket
import time
from dataclasses import dataclass, field
from typing import Any

from rcmlconf.errors import ValueTextError
from rcmlconf.fuzz.owed import UNFRAMED, Owed
from rcmlconf.fuzz.rctp_drafts import STOP_UNANSWERED
from rcmlconf.fuzz.steps import CLIENT_PORT, SESSION, Step, TestCase
from rcmlconf.pcap.writer import Payload
from rcmlconf.rctp.errors import RemoteProtocolError
from rcmlconf.rctp.fields import parse_session, parse_transport
from rcmlconf.rctp.messages import Request, Response
from rcmlconf.rctp.reader import MessageReader

Address = tuple[str, int]
#: D-FUZZ-4: the answer to a request that cannot be framed needs no robot (D-RCTP-10): it is
#: due within this share of the wait (1 s of 5).
FRAMING_SHARE = 0.2
#: How long the drain at the end of a case waits for one more message, in seconds.
IDLE = 0.004
#: The most the fuzzer reads of one case's answers (a target that floods it gets cut off).
MOST_READ = 4 * 1024 * 1024


@dataclass(slots=True)
class Outcome:
    """What one run of a test case saw."""

    payloads: list[Payload] = field(default_factory=list)
    #: Why the prefix did not reach its state (None: it did).
    missed: str | None = None
    owed: Owed = field(default_factory=Owed)
    #: Answers to the fuzzer's requests, in order: their status codes.
    statuses: list[int] = field(default_factory=list)
    #: "open", "closed" or "reset" as the case ended; "refused": no connection at all;
    #: "finished": the target closed after the fuzzer's own FIN (D-FUZZ-1's end of a case).
    end: str = "open"
    #: An owed answer that did not come within the wait while the connection stayed open.
    unanswered: str | None = None
    #: The server's response could not be framed (R-RCTP-1, D-RCTP-10): where.
    garbled: str | None = None
    #: The fuzzer's own addresses: what the target sent came from any other.
    ours: set[Address] = field(default_factory=set)

    @property
    def due(self) -> list[str]:
        """The owed answers that never came."""
        return self.owed.requests[len(self.statuses) :]

    def process_output(self) -> dict[str, Any] | None:
        """How a process started for this run alone ended (a client's, D-FUZZ-8); None here."""
        return None


class _Session:
    """What the target chose in this run: the session's ID, the data stream's port and tag."""

    def __init__(self) -> None:
        self.session = b"none"
        self.server_port: int | None = None
        self.tag: int | None = None
        self.stream: int | None = None

    def learn(self, request: Request | None, response: Response) -> None:
        if request is None or response.status != 200:
            return
        with contextlib.suppress(ValueTextError):
            if request.method == "CONNECT" and (text := response.headers.get("Session")):
                self.session = parse_session(text).id.encode("latin-1")
            if request.method == "SETUP" and (text := response.headers.get("Transport")):
                given = parse_transport(text)
                self.server_port, self.tag, self.stream = (
                    given.server_port,
                    given.tag,
                    given.stream,
                )


class RctpRunner:
    """Runs test cases against the server at `address`. `wait` bounds every answer (D-FUZZ-4)."""

    def __init__(self, address: Address, *, wait: float) -> None:
        self.address = address
        self.wait = wait
        family = socket.AF_INET6 if ":" in address[0] else socket.AF_INET
        self.udp = socket.socket(family, socket.SOCK_DGRAM)
        self.udp.bind((address[0], 0))
        self.udp.setblocking(False)
        self.udp_address: Address = self.udp.getsockname()[:2]

    def close(self) -> None:
        self.udp.close()

    def run(self, case: TestCase) -> Outcome:
        self._forget_udp()
        out = Outcome()
        try:
            sock = socket.create_connection(self.address, timeout=self.wait)
        except ConnectionRefusedError:
            out.end = "refused"
            return out
        except OSError as error:
            out.end = "refused"
            out.missed = f"could not connect: {error}"
            return out
        with sock:
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            _Exchange(self, sock, out).run(case)
        return out

    def _forget_udp(self) -> None:
        """Datagrams of an earlier case's session (a stream still playing) are not this case's."""
        with contextlib.suppress(BlockingIOError, OSError):
            for _ in range(10_000):
                self.udp.recv(65535)


class _Exchange:
    def __init__(self, runner: RctpRunner, sock: socket.socket, out: Outcome) -> None:
        self.runner, self.sock, self.out = runner, sock, out
        self.local: Address = sock.getsockname()[:2]
        out.ours |= {self.local, runner.udp_address}
        self.session = _Session()
        self.reader = MessageReader()
        #: The fuzzer's requests framed so far, to match answers with (None: unframeable).
        self.sent: list[Request | None] = []
        self._sent_reader = MessageReader()
        self.read = 0
        #: D-FUZZ-2's `stop unanswered`: the server's STOP is held, not answered.
        self.hold_stop = False
        self.stop_held = False

    def run(self, case: TestCase) -> None:
        out = self.out
        for step in case.prefix:
            self._send(step)
            self._answers(len(out.owed.requests))
            if out.end != "open" or out.unanswered or out.garbled:
                out.missed = out.missed or "the connection ended during the prefix"
                return
            if not out.statuses or out.statuses[-1] != 200:
                out.missed = f"the prefix's request was answered {out.statuses[-1:] or 'nothing'}"
                return
        if case.state == STOP_UNANSWERED and not self._await_stop():
            return
        for step in case.steps:
            self._send(step)
            if step.channel == "control":
                self._answers(len(out.owed.requests))
            if out.end != "open" or out.unanswered or out.garbled:
                return
        self._drain((case.steps or case.prefix)[-1].channel == "control")

    def _await_stop(self) -> bool:
        """D-FUZZ-2: the server's STOP for the stream's receive timeout (R-RCTP-45), within the
        wait; it stays unanswered. False (the prefix missed) when it does not come."""
        self.hold_stop = True
        deadline = time.monotonic() + self.runner.wait
        while not self.stop_held and self.out.end == "open" and not self.out.garbled:
            left = deadline - time.monotonic()
            if left <= 0:
                break
            self._wait_once(left)
        if not self.stop_held:
            self.out.missed = f"no STOP for the receive timeout within {self.runner.wait:g} s"
        return self.stop_held

    # -- sending --

    def _send(self, step: Step) -> None:
        if step.channel == "control":
            data = step.data.replace(SESSION, self.session.session).replace(
                CLIENT_PORT, str(self.runner.udp_address[1]).encode()
            )
            self._record("tcp", self.local, self.runner.address, data)
            self.out.owed.sent(data)
            self._frame_sent(data)
            try:
                self.sock.sendall(data)
            except (BrokenPipeError, ConnectionResetError):
                self.out.end = "reset"
            except OSError:
                self.out.end = "closed"
            return
        port = self.session.server_port
        if port is None:
            return  # no stream set up: the step has nowhere to go
        datagram = bytearray(step.data)
        if step.tagged and self.session.tag is not None and len(datagram) >= 8:
            datagram[4:8] = self.session.tag.to_bytes(4, "big")
        stream = self.session.stream
        if step.tagged and stream is not None and len(datagram) >= 18 and datagram[17] == 1:
            datagram[17] = stream
        destination = (self.runner.address[0], port)
        self._record("udp", self.runner.udp_address, destination, bytes(datagram))
        with contextlib.suppress(OSError):
            self.runner.udp.sendto(bytes(datagram), destination)

    def _frame_sent(self, data: bytes) -> None:
        self._sent_reader.feed(data)
        while True:
            try:
                message = self._sent_reader.next_message()
            except RemoteProtocolError:
                self.sent.append(None)
                return
            if message is None:
                return
            self.sent.append(message if isinstance(message, Request) else None)

    # -- receiving --

    def _answers(self, wanted: int) -> None:
        """Read until `wanted` answers came, the connection ended, or the wait ran out."""
        start = time.monotonic()
        while len(self.out.statuses) < wanted and self.out.end == "open" and not self.out.garbled:
            due = self.out.due
            wait = self.runner.wait
            if due and due[0].startswith(UNFRAMED):
                wait *= FRAMING_SHARE
            left = start + wait - time.monotonic()
            if left <= 0:
                self.out.unanswered = self.out.due[0] if self.out.due else None
                return
            self._wait_once(left)

    def _drain(self, control_last: bool) -> None:
        """What comes after the last step: extra answers, the server's requests, a close.

        D-FUZZ-1: where the last step went on the control connection (`control_last`) and what
        was sent frames whole, the fuzzer sends its FIN, and the target's close ends the case
        at once ("finished"). Otherwise, or where the target leaves the connection open, the
        control connection's silence for IDLE ends it; the data stream's datagrams are read
        meanwhile but do not keep it going (a playing stream never falls silent)."""
        finishing = control_last and self._frames_whole()
        if finishing:
            with contextlib.suppress(OSError):
                self.sock.shutdown(socket.SHUT_WR)
        last = time.monotonic()
        end = last + 10 * IDLE
        while self.out.end == "open" and not self.out.garbled:
            now = time.monotonic()
            left = min(last + IDLE, end) - now
            if left <= 0:
                return
            if self._wait_once(left) == "tcp":
                last = time.monotonic()
        if finishing and self.out.end == "closed":
            self.out.end = "finished"

    def _frames_whole(self) -> bool:
        """Whether every byte sent frames whole, so that the fuzzer's FIN cuts no request short."""
        return self._sent_reader.buffered == 0 and None not in self.sent

    def _wait_once(self, timeout: float) -> str | None:
        """One wait for either socket: which one had something ("tcp" first), None: neither."""
        ready, _, _ = select.select([self.sock, self.runner.udp], [], [], timeout)
        if self.runner.udp in ready:
            self._udp()
        if self.sock in ready:
            self._tcp()
            return "tcp"
        return "udp" if ready else None

    def _udp(self) -> None:
        with contextlib.suppress(BlockingIOError, OSError):
            for _ in range(64):
                data, source = self.runner.udp.recvfrom(65535)
                self._record("udp", source[:2], self.runner.udp_address, data)

    def _tcp(self) -> None:
        try:
            data = self.sock.recv(65536)
        except ConnectionResetError:
            self.out.end = "reset"
            return
        except OSError:
            self.out.end = "closed"
            return
        if not data:
            self.out.end = "closed"
            return
        self.read += len(data)
        self._record("tcp", self.runner.address, self.local, data)
        if self.read > MOST_READ:
            self.out.garbled = f"more than {MOST_READ} bytes of answers in one case"
            return
        self.reader.feed(data)
        while True:
            try:
                message = self.reader.next_message()
            except RemoteProtocolError as error:
                self.out.garbled = f"{error.reason} at byte {error.offset} ({error.rule})"
                return
            if message is None:
                return
            if isinstance(message, Response):
                self._response(message)
            else:
                self._own_request(message)

    def _response(self, response: Response) -> None:
        index = len(self.out.statuses)
        request = self.sent[index] if index < len(self.sent) else None
        self.out.statuses.append(response.status)
        self.out.owed.answered(index, response.status)
        self.session.learn(request, response)

    def _own_request(self, request: Request) -> None:
        """R-RCTP-24: a client answers the server's WRITE, STOP and BYE 200."""
        if self.hold_stop and request.method == "STOP" and not self.stop_held:
            self.stop_held = True  # D-FUZZ-2: left unanswered
            return
        cseq = request.headers.get("CSeq") or "0"
        answer = (
            f"RCTP/2.0 200 OK\r\nCSeq: {cseq}\r\nSession: {self.session.session.decode()}\r\n\r\n"
        ).encode("latin-1", "replace")
        self._record("tcp", self.local, self.runner.address, answer)
        if request.method == "BYE":
            self.out.owed.close_allowed = "R-RCTP-23: the server's BYE is answered"
        with contextlib.suppress(OSError):
            self.sock.sendall(answer)

    def _record(self, transport: str, source: Address, destination: Address, data: bytes) -> None:
        self.out.payloads.append(Payload(time.time(), transport, source, destination, data))
