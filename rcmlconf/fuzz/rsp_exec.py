"""One test case against an RSP robot, on a real UDP socket (D-FUZZ-1, D-FUZZ-4).

The core's `LocalEndpoint` opens the session and takes it to the case's state (its HELLO,
the robot's WELCOME, then DOWNLINKs every T). Then the steps go out, each with the live
session's ID, the next sequence numbers, a stamp on the session's clock and the robot's last
sequence number in its header, but for the field its mutation changed. A BYE of the same
numbering ends the session, so that a robot of one session at a time takes the next case.
"""

from __future__ import annotations

import select
import socket
import time

from rcmlconf.errors import ProtocolError
from rcmlconf.fuzz.rctp_exec import Address, Outcome
from rcmlconf.fuzz.rsp_cases import IDLE, drive, filled
from rcmlconf.fuzz.steps import TestCase
from rcmlconf.pcap.writer import Payload
from rcmlconf.rsp.codec import Bye, ByeReason, PacketType, codec_for
from rcmlconf.rsp.codec.bodies import Packet
from rcmlconf.rsp.codec.header import LAST_AT, SEQUENCE_AT, TYPE_AT
from rcmlconf.rsp.model import RobotModel
from rcmlconf.rsp.session import events
from rcmlconf.rsp.session.local import LocalEndpoint

#: How many periods the prefix runs once the state is asked for, and the drain after the steps.
PREFIX_PERIODS, DRAIN_PERIODS = 3, 2


class RspRunner:
    def __init__(self, address: Address, model: RobotModel, *, wait: float) -> None:
        self.address = address
        self.model = model
        self.codec = codec_for(model)
        self.wait = wait

    def run(self, case: TestCase) -> Outcome:
        out = Outcome()
        family = socket.AF_INET6 if ":" in self.address[0] else socket.AF_INET
        with socket.socket(family, socket.SOCK_DGRAM) as sock:
            sock.connect(self.address)
            sock.setblocking(False)
            _Session(self, sock, out).run(case)
        return out


class _Session:
    def __init__(self, runner: RspRunner, sock: socket.socket, out: Outcome) -> None:
        self.runner, self.sock, self.out = runner, sock, out
        self.local: Address = sock.getsockname()[:2]
        out.ours.add(self.local)
        self.endpoint = LocalEndpoint(runner.model)
        self.start = time.monotonic()
        self.last_sent: bytes | None = None
        self.robot_sequence = 0

    def run(self, case: TestCase) -> None:
        if case.state == IDLE:
            self._hellos(case)
            return
        endpoint, out = self.endpoint, self.out
        endpoint.connect(self._now())
        self._flush()
        deadline = time.monotonic() + self.runner.wait
        while endpoint.state == "hello" and time.monotonic() < deadline and out.end == "open":
            self._wait_until(endpoint.get_timer())
        if endpoint.state != "open":
            out.missed = "no WELCOME" if endpoint.state == "hello" else "the HELLO was refused"
            return
        if not drive(endpoint, self.runner.model, case.state):
            out.missed = f"the model has nothing for {case.state}"
            return
        self._periods(PREFIX_PERIODS)
        if endpoint.state != "open" or out.end != "open":
            out.missed = "the session ended during the prefix"
            return
        newest = 0
        for index, step in enumerate(case.steps, start=1):
            data = self._filled(step.data, step.kind, index)
            if step.kind == "rsp-sequence" and len(data) > SEQUENCE_AT + 2:
                newest = max(newest, int.from_bytes(data[SEQUENCE_AT : SEQUENCE_AT + 2], "big"))
            self._send(data)
        self._periods(DRAIN_PERIODS, beat=False)
        count = len(case.steps) + 1
        self._send(self._bye(count))
        if newest:  # a step's number moved the robot's newest on: a BYE past it too (R-RSP-14)
            self._send(self._bye(count, after=newest))

    def _hellos(self, case: TestCase) -> None:
        """No session first: each step is a HELLO as its mutation left it. A session one of them
        opened is ended with BYE, so the robot's sessions do not fill up."""
        for step in case.steps:
            self._send(step.data)
        self._periods(DRAIN_PERIODS + 1, beat=False)
        codec = self.runner.codec
        for payload in list(self.out.payloads):
            data = payload.data
            ours = payload.source == self.runner.address and len(data) > TYPE_AT
            if ours and data[TYPE_AT] == PacketType.WELCOME:
                try:
                    welcome = codec.pull_header(data)
                except ProtocolError:
                    continue  # a WELCOME the codec refuses: its session is the robot's worry
                header = welcome._replace(
                    type=PacketType.BYE, sequence=1, last_received=welcome.sequence, buffer=0
                )
                self._send(codec.push_packet(Packet(header, Bye(ByeReason.CLOSED))))

    # -- time ---------------------------------------------------------------------------------

    def _now(self) -> float:
        return time.monotonic() - self.start

    def _periods(self, count: int, *, beat: bool = True) -> None:
        """Run the session `count` periods: the endpoint's beats (or only reading)."""
        until = time.monotonic() + count * self.runner.model.period
        while time.monotonic() < until and self.out.end == "open":
            timer = self.endpoint.get_timer() if beat else None
            self._wait_until(
                min(timer, until - self.start) if timer is not None else until - self.start
            )

    def _wait_until(self, at: float | None) -> None:
        left = max((at if at is not None else self._now() + 0.05) - self._now(), 0.0)
        ready, _, _ = select.select([self.sock], [], [], min(left, 0.25))
        if ready:
            self._receive()
        now = self._now()
        self.endpoint.handle_timer(now)
        self._flush()

    # -- the wire -----------------------------------------------------------------------------

    def _receive(self) -> None:
        for _ in range(64):
            try:
                data = self.sock.recv(65535)
            except BlockingIOError:
                return
            except ConnectionRefusedError:
                self.out.end = "refused"  # ICMP port unreachable: nothing listens there now
                return
            except OSError:
                return
            self._record(self.runner.address, self.local, data)
            if len(data) > TYPE_AT:
                self.out.statuses.append(data[TYPE_AT])
            if len(data) >= LAST_AT:
                self.robot_sequence = int.from_bytes(data[SEQUENCE_AT : SEQUENCE_AT + 2], "big")
            self.endpoint.receive_datagram(data, self._now())
            while (event := self.endpoint.next_event()) is not None:
                if isinstance(event, events.SessionClosed) and event.by_peer:
                    self.out.owed.close_allowed = "the robot's BYE"

    def _flush(self) -> None:
        """The endpoint's own packets: valid, and what the steps' headers follow."""
        for data in self.endpoint.datagrams_to_send(self._now()):
            if len(data) > TYPE_AT and data[TYPE_AT] != PacketType.HELLO:
                self.last_sent = data
            self._send(data)

    def _send(self, data: bytes) -> None:
        if not data:
            return
        self._record(self.local, self.runner.address, data)
        try:
            self.sock.send(data)
        except ConnectionRefusedError:
            self.out.end = "refused"
        except OSError:
            pass

    def _filled(self, data: bytes, kind: str, index: int) -> bytes:
        """The step with the live session's header fields, but the one `kind` changed."""
        return filled(data, kind, self.last_sent, index, self.robot_sequence)

    def _bye(self, index: int, after: int | None = None) -> bytes:
        """BYE (reason 0) numbered on from the session's packets, or from `after`."""
        header = self.runner.codec.pull_header(self.last_sent) if self.last_sent else None
        if header is None:
            return b""
        bye = Packet(header._replace(type=PacketType.BYE, buffer=0), Bye(ByeReason.CLOSED))
        data = self._filled(self.runner.codec.push_packet(bye), "", index)
        if after is None:
            return data
        sequence = ((after + 1) % 65536).to_bytes(2, "big")
        return data[:SEQUENCE_AT] + sequence + data[SEQUENCE_AT + 2 :]

    def _record(self, source: Address, destination: Address, data: bytes) -> None:
        self.out.payloads.append(Payload(time.time(), "udp", source, destination, data))
