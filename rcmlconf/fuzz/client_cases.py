"""Test cases for an RCTP/2.0 client: the state its scenario reaches, then mutated steps of the
server's (D-FUZZ-8).

The client's own requests take it to the state (D-RCTP-31), so a case's prefix is the state's
name. Its steps are the answer to the request that enters the state, mutated (`answer-*`
kinds); requests of the server's, mutated (`push-*`: a data-change WRITE of the event access,
STOP, BYE); and, where the stream plays, datagrams of the server's, mutated (`data-*`: DATA of
the stream and FLOW requests, and the answer to the client's next heartbeat).
"""

from __future__ import annotations

import random
from dataclasses import dataclass

from rcmlconf.fuzz import mutate
from rcmlconf.fuzz.rctp_cases import flow_request
from rcmlconf.fuzz.rctp_drafts import Draft, answer
from rcmlconf.fuzz.rctp_robot import RobotPaths
from rcmlconf.fuzz.steps import CSEQ, SESSION, TRANSPORT, Step, TestCase
from rcmlconf.rctp.bodies import ValuesCodec
from rcmlconf.rctp.datastream.flow import Direction, HeartbeatAck, encode_flow
from rcmlconf.rctp.datastream.packets import PayloadType, push_datagram
from rcmlconf.rctp.datastream.values import stream_codec
from rcmlconf.rctp.messages import VALUES_TYPE

ANSWER, PUSH, DATA = "answer-", "push-", "data-"
#: The kinds of a step held for the client's next heartbeat, which it answers (D-FUZZ-8).
HEARTBEAT_KINDS = frozenset(DATA + name for name in mutate.HEARTBEAT_ACK)
#: A heartbeat ACK whose request id and T1 the played server fills in from the request.
_ACK = HeartbeatAck(0, 0, 0, 0)
_SESSION, _CSEQ = SESSION.decode(), CSEQ.decode()


@dataclass(frozen=True, slots=True)
class Entry:
    """The client's request that enters a state: its method, its target's node path (None:
    any), and whether the state is reached only once it is answered 200."""

    method: str
    path: str | None = None


def entries(robot: RobotPaths) -> dict[str, Entry]:
    """D-FUZZ-8's states of a client, in the order its scenario reaches them; a state the
    robot has no node for is left out."""
    found = {"connecting": Entry("CONNECT"), "reading": Entry("READ"), "writing": Entry("ACQUIRE")}
    if robot.event is not None:
        found["event playing"] = Entry("GO", robot.event.path)
    if robot.stream is not None:
        found["stream set up"] = Entry("SETUP", robot.stream.path)
        found["stream playing"] = Entry("GO", robot.stream.path)
    return found


def _fields(*more: tuple[str, str]) -> tuple[tuple[str, str], ...]:
    return (("CSeq", _CSEQ), ("Session", _SESSION), *more)


class ClientCases:
    """Makes test cases for a client of the robot `robot` (the harness's, D-RCTP-31)."""

    def __init__(self, robot: RobotPaths) -> None:
        self.robot = robot
        self.entries = entries(robot)
        self._answers = {state: self._answer(state) for state in self.entries}
        self._pushes = self._server_requests()

    @property
    def states(self) -> tuple[str, ...]:
        return tuple(self.entries)

    def kinds(self, state: str) -> tuple[str, ...]:
        kinds = [ANSWER + name for name in mutate.ANSWER]
        kinds += [PUSH + name for name in (*mutate.CONTROL, "bytes")]
        if state == "stream playing":
            kinds += [DATA + name for name in (*mutate.DATA, *mutate.HEARTBEAT_ACK)]
        return tuple(kinds)

    def make(self, state: str, kind: str, rng: random.Random, count: int = 1) -> TestCase:
        """A case in `state` whose first step `kind` made; an answer's mutation only leads."""
        made = [self._step(state, kind, rng)]
        others = [k for k in self.kinds(state) if not k.startswith(ANSWER)]
        for _ in range(count - 1):
            if others:
                made.append(self._step(state, rng.choice(others), rng))
        return TestCase(state, (), tuple(made), tuple(s.kind for s in made))

    def _step(self, state: str, kind: str, rng: random.Random) -> Step:
        if kind.startswith(ANSWER):
            name = kind.removeprefix(ANSWER)
            return Step("control", mutate.ANSWER[name](self._answers[state], rng).render(), kind)
        if kind in HEARTBEAT_KINDS:
            body = mutate.HEARTBEAT_ACK[kind.removeprefix(DATA)](encode_flow(_ACK), rng)
            return Step("data", push_datagram(0, 0, 0, [(int(PayloadType.FLOW), body, 0)]), kind)
        if kind.startswith(DATA):
            name = kind.removeprefix(DATA)
            data = mutate.DATA[name](self._datagram(rng, flow=name.startswith("flow-")), rng)
            return Step("data", data, kind, tagged=name not in ("tag", "stream-id"))
        name = kind.removeprefix(PUSH)
        origin = rng.choice(self._pushes)
        if name == "bytes":
            data = mutate.flip_bytes(origin.render(), rng)
        else:
            data = mutate.CONTROL[name](origin, rng).render()
        return Step("control", data, kind, origin=origin.render())

    def _answer(self, state: str) -> Draft:
        """The valid 200 answer to the request that enters `state`, as a template."""
        entry = self.entries[state]
        if entry.method == "CONNECT":
            return answer(200, "OK", (("CSeq", _CSEQ), ("Session", f"{_SESSION};timeout=60")))
        if entry.method == "READ" and self.robot.readable is not None:
            fields = _fields(("Content-Type", VALUES_TYPE))
            return answer(200, "OK", fields, self.robot.zero_body(self.robot.readable))
        if entry.method == "SETUP":
            return answer(200, "OK", _fields(("Transport", TRANSPORT.decode())))
        return answer(200, "OK", _fields())

    def _server_requests(self) -> list[Draft]:
        """The valid requests a server sends (R-RCTP-25): a data-change WRITE of the event
        access with its readable nodes' zero values, STOP of each access that plays, BYE."""
        found = [Draft("BYE", "*", _fields(("Reason", "shutdown")))]
        event, stream = self.robot.event, self.robot.stream
        if event is not None:
            nodes = event.readable()
            body = ValuesCodec(nodes, event.path, "R-RCTP-6").encode(
                {node.name: node.zero() for node in nodes}
            )
            names = ", ".join(node.name for node in nodes)
            fields = _fields(("Nodes", names), ("Content-Type", VALUES_TYPE))
            found.append(Draft("WRITE", event.path, fields, body))
            found.append(Draft("STOP", event.path, _fields()))
        if stream is not None:
            found.append(Draft("STOP", stream.path, _fields(("Reason", "timeout"))))
        return found

    def _datagram(self, rng: random.Random, flow: bool) -> bytes:
        """A valid datagram of the server's on the playing stream (stream 1, its header's
        numbers filled in when sent): a FLOW request, whose last field is what the FLOW
        mutations change, or DATA of the stream's readable nodes."""
        body, stream = flow_request(rng)
        kind = int(PayloadType.FLOW)
        access = self.robot.stream
        if not flow and access is not None and access.readable() and rng.random() < 0.6:
            codec = stream_codec(access, Direction.READ)
            kind, stream = int(PayloadType.DATA), 1
            body = codec.encode({node.name: node.zero() for node in codec.nodes})
        return push_datagram(0, 0, 0, [(kind, body, stream)])
