"""An RSP local system as the fuzzer sees it (D-FUZZ-9): started for each case with the
played robot's address, taken by its own scenario (D-RSP-24) to the case's state, sent the
steps, probed and judged.

The played robot is the core's `RobotEndpoint` on a UDP socket of the fuzzer's. Each case is
a new process of `--client-command` and a new session, so a crash is the case's own and there
is nothing to restart between cases.
"""

from __future__ import annotations

import contextlib
import select
import socket
import time
from dataclasses import dataclass

from rcmlconf.errors import ProtocolError
from rcmlconf.fuzz.local_cases import HELLO, MEMORY_EVENT, WELCOMED
from rcmlconf.fuzz.monitor import TargetProcess
from rcmlconf.fuzz.oracles import CRASH, HANG, Verdict, violation
from rcmlconf.fuzz.per_case import StartedOutcome, exit_after_run, run_started, with_url
from rcmlconf.fuzz.rctp_exec import Address, Outcome
from rcmlconf.fuzz.rsp_cases import filled, zeros
from rcmlconf.fuzz.steps import TestCase
from rcmlconf.pcap.writer import Payload
from rcmlconf.rsp.codec import Bye, PacketType, codec_for
from rcmlconf.rsp.codec.header import SEQUENCE_AT, TYPE_AT
from rcmlconf.rsp.layout import HEADER_SIZE, NONCE_SIZE
from rcmlconf.rsp.model import DeviceKind, RobotModel
from rcmlconf.rsp.session import events
from rcmlconf.rsp.session.robot import RobotEndpoint

#: D-RSP-24's run lasts 10 s after WELCOME; a local system not in the state by then will not be.
SCENARIO = 10.0


@dataclass(slots=True)
class LocalOutcome(StartedOutcome):
    #: The run ended: the played robot's BYE, or the local system's.
    ended: bool = False


class LocalTarget:
    role = "local"
    fresh = True

    def __init__(
        self,
        model: RobotModel,
        listen: Address,
        command: str,
        *,
        wait: float,
        connect_timeout: float,
    ) -> None:
        self.model = model
        self.codec = codec_for(model)
        self.listen = listen
        self.wait = wait
        self.connect_timeout = connect_timeout
        address = f"{listen[0]}:{listen[1]}"
        self.command = with_url(command, address)
        family = socket.AF_INET6 if ":" in listen[0] else socket.AF_INET
        self.sock = socket.socket(family, socket.SOCK_DGRAM)
        try:
            self.sock.bind(listen)
        except OSError:
            self.sock.close()
            raise
        self.sock.setblocking(False)

    def run(self, case: TestCase) -> Outcome:
        self._drain()
        out = LocalOutcome(state=case.state)
        out.ours = {self.listen}
        run_started(self.command, out, lambda process: _PlayedRun(self, case, process, out).run())
        return out

    def _drain(self) -> None:
        """What an earlier case's local system still sent is not this case's."""
        for _ in range(10_000):
            try:
                self.sock.recv(65535)
            except OSError:
                return

    def judge(self, out: Outcome) -> Verdict | None:
        assert isinstance(out, LocalOutcome)
        if out.missed is not None:
            return None
        exit = out.exit
        if exit is not None and exit.status != 0 and out.may_end is None and not out.ended:
            text = f"the local system's process {exit.text()} in {out.state}, its run not ended"
            return Verdict(CRASH, "D-RSP-24", text)
        if out.unanswered is not None and out.may_end is None:
            return Verdict(HANG, "R-RSP-42", out.unanswered)
        if out.may_end is not None:
            return None
        return violation(out.payloads, out.ours, None, self.listen[1], model=self.model)

    def alive(self) -> Verdict | None:
        return None

    def close(self) -> None:
        self.sock.close()


class _PlayedRun:
    """One case: the played robot's session with the local system the case started."""

    def __init__(
        self, target: LocalTarget, case: TestCase, process: TargetProcess, out: LocalOutcome
    ) -> None:
        self.target, self.case, self.process, self.out = target, case, process, out
        self.robot = RobotEndpoint(target.model)
        self.start = time.monotonic()
        self.peer: Address | None = None
        #: The robot's newest valid packet, and the local system's newest sequence number.
        self.last: bytes | None = None
        self.peer_last = 0
        self.reached: float | None = None
        self.heard_since = False
        self.memory_sent = self.memory_taken = self.downlinked = False

    def _now(self) -> float:
        return time.monotonic() - self.start

    def run(self) -> None:
        out, target = self.out, self.target
        deadline = time.monotonic() + target.connect_timeout + SCENARIO
        while self.reached is None and not out.ended and time.monotonic() < deadline:
            if self.process.exited() is not None:
                break
            self._turn()
        if self.reached is None:
            out.missed = f"the local system did not reach {self.case.state}"
            out.exit = self.process.exited()
            return
        # The probe: a local system sends every T (R-RSP-42); within the wait it sends again.
        self.heard_since = False
        until = time.monotonic() + target.wait
        while not self.heard_since and not out.ended and time.monotonic() < until:
            if self.process.exited() is not None:
                break
            self._turn()
        if not self.heard_since and not out.ended and self.process.exited() is None:
            out.unanswered = f"no packet from the local system within {target.wait:g} s"
            return
        if not out.ended and self.process.exited() is None:
            self.robot.close(self._now())  # the robot's BYE ends the run (D-RSP-24)
            self._flush()
            out.ended = True
        out.exit = exit_after_run(self.process)

    def _turn(self) -> None:
        timer = self.robot.get_timer()
        left = 0.02 if timer is None else min(max(timer - self._now(), 0.0), 0.02)
        ready, _, _ = select.select([self.target.sock], [], [], left)
        if ready:
            self._receive()
        self.robot.handle_timer(self._now())
        self._advance()
        self._flush()

    def _receive(self) -> None:
        for _ in range(64):
            try:
                data, source = self.target.sock.recvfrom(65535)
            except OSError:
                return
            peer: Address = source[:2]
            self._record(peer, self.target.listen, data)
            if self.peer is None and len(data) > TYPE_AT and data[TYPE_AT] == PacketType.HELLO:
                self.peer = peer
            if peer != self.peer:
                continue  # not the case's local system
            self.heard_since = True
            if len(data) > TYPE_AT and data[TYPE_AT] == PacketType.DOWNLINK:
                self.downlinked = True  # it took the WELCOME: the session is open on its side
            if len(data) > SEQUENCE_AT + 2 and data[TYPE_AT] != PacketType.HELLO:
                self.peer_last = int.from_bytes(data[SEQUENCE_AT : SEQUENCE_AT + 2], "big")
            self.robot.receive_datagram(data, peer, self._now())
            while (event := self.robot.next_event()) is not None:
                if isinstance(event, events.SessionClosed):
                    self.out.ended = True  # its BYE, or a session timeout
                elif isinstance(event, events.Acknowledged):
                    self.memory_taken = True

    def _advance(self) -> None:
        """Take the session on to the case's state, and send the steps once there."""
        state = self.case.state
        if self.reached is not None or self.robot.session is None or state == HELLO:
            return
        if not self.downlinked:
            return
        if state == MEMORY_EVENT and not self.memory_taken:
            # One memory event, once the local system requests its device; then its ACK.
            if not self.memory_sent:
                kind = DeviceKind.MEMORY_EVENT
                device = next(d for d in self.target.model.devices if d.kind is kind)
                self.memory_sent = self.robot.occur(device.name, zeros(device)) is not None
            return
        if state in (WELCOMED, MEMORY_EVENT):
            self._steps()

    def _steps(self) -> None:
        self.reached = time.monotonic()
        for index, step in enumerate(self.case.steps, start=1):
            self._send(filled(step.data, step.kind, self.last, index, self.peer_last))
            self._may_end(step.data)

    def _may_end(self, data: bytes) -> None:
        """A step the core reads as a BYE of the session ends the run (D-RSP-24)."""
        try:
            packet = self.target.codec.pull_packet(data)
        except (ProtocolError, ValueError):
            return
        if isinstance(packet.body, Bye):
            self.out.may_end = "D-RSP-24: the robot's BYE ends the run"

    def _flush(self) -> None:
        for data, _ in self.robot.datagrams_to_send(self._now()):
            welcome = len(data) > TYPE_AT and data[TYPE_AT] == PacketType.WELCOME
            if welcome and self.case.state == HELLO and self.reached is None and self.case.steps:
                data = self._welcome(data)
                self.reached = time.monotonic()
            self.last = data if self.reached is None or self.last is None else self.last
            self._send(data)

    def _welcome(self, valid: bytes) -> bytes:
        """The step in the WELCOME's place, with the session's fields and the HELLO's nonce."""
        step = self.case.steps[0]
        data = bytearray(filled(step.data, step.kind, valid, 0, self.peer_last))
        nonce = slice(HEADER_SIZE, HEADER_SIZE + NONCE_SIZE)
        if len(data) >= nonce.stop and len(valid) >= nonce.stop:
            data[nonce] = valid[nonce]
        return bytes(data)

    def _send(self, data: bytes) -> None:
        if self.peer is None or not data:
            return
        self._record(self.target.listen, self.peer, data)
        with contextlib.suppress(OSError):
            self.target.sock.sendto(data, self.peer)

    def _record(self, source: Address, destination: Address, data: bytes) -> None:
        if len(self.out.payloads) < 10_000:
            self.out.payloads.append(Payload(time.time(), "udp", source, destination, data))
