"""Test cases for an RCTP/2.0 server: a valid prefix to a state, then mutated steps (D-FUZZ-1).

A prefix's requests are numbered from CSeq 1 (D-RCTP-6); the steps go on from there, so a step
whose mutation left its `CSeq` alone is next in order. Data-stream steps go only where a
stream is set up: they need its port and tag (D-RCTP-18, D-RCTP-19).
"""

from __future__ import annotations

import random
from collections.abc import Sequence

from rcmlconf.fuzz import mutate
from rcmlconf.fuzz.rctp_drafts import STATES, STOP_UNANSWERED, Draft, moves, prefix
from rcmlconf.fuzz.rctp_robot import RobotPaths
from rcmlconf.fuzz.steps import Step, TestCase
from rcmlconf.rctp.datastream.flow import (
    Direction,
    HeartbeatRequest,
    IntervalSet,
    TimeoutSet,
    encode_flow,
)
from rcmlconf.rctp.datastream.packets import PayloadType, push_datagram

#: The kinds that change bytes, not the grammar: any message, any state.
BYTES, SPLICE = "bytes", "splice"
CONTROL_KINDS = (*mutate.CONTROL, BYTES, SPLICE)
DATA_KINDS = tuple(f"data-{name}" for name in mutate.DATA)
#: The states with a data stream to send on.
STREAM_STATES = frozenset({"stream ready", "playing", STOP_UNANSWERED})
#: D-FUZZ-2: the receive timeout asked for before the server's STOP, at the least (the
#: conformance cases' shortest, so that one the server takes is quick to wait out).
SHORTEST_TIMEOUT = 0.3


class RctpCases:
    """Makes test cases for one robot; `seeds` are whole control messages to splice with."""

    def __init__(self, robot: RobotPaths, seeds: Sequence[bytes]) -> None:
        self.robot = robot
        self.seeds = list(seeds) or [d.with_cseq(1).render() for d in moves(robot)]
        self._moves = moves(robot)
        self.prefixes: dict[str, list[Draft]] = {}
        for state in STATES:
            found = prefix(state, robot)
            if found is not None:
                self.prefixes[state] = found

    @property
    def states(self) -> tuple[str, ...]:
        return tuple(self.prefixes)

    def kinds(self, state: str) -> tuple[str, ...]:
        """The mutation kinds that apply in `state`."""
        if state in STREAM_STATES:
            return (*CONTROL_KINDS, *DATA_KINDS)
        return CONTROL_KINDS

    def make(self, state: str, kind: str, rng: random.Random, count: int = 1) -> TestCase:
        """A case in `state` whose steps `kind` made (`count` of them, the first mutated)."""
        drafts = self.prefixes[state]
        steps = tuple(
            Step("control", d.with_cseq(n).render()) for n, d in enumerate(drafts, start=1)
        )
        if state == STOP_UNANSWERED:
            steps += (self._timeout_request(rng),)
        cseq = len(drafts) + 1
        made: list[Step] = []
        for index in range(count):
            chosen = kind if index == 0 else rng.choice(self.kinds(state))
            made.append(self._step(chosen, cseq + index, rng))
        return TestCase(state, steps, tuple(made), tuple(s.kind for s in made))

    def _step(self, kind: str, cseq: int, rng: random.Random) -> Step:
        if kind.startswith("data-"):
            name = kind.removeprefix("data-")
            base = self._datagram(rng, flow=name.startswith("flow-"), data=name == "payload-body")
            data = mutate.DATA[name](base, rng)
            return Step("data", data, kind, tagged=name not in ("tag", "stream-id"))
        draft = rng.choice(self._moves).with_cseq(cseq)
        if kind == BYTES:
            return Step("control", mutate.flip_bytes(draft.render(), rng), kind)
        if kind == SPLICE:
            seed = rng.choice(self.seeds)
            return Step("control", mutate.splice(draft.render(), seed, rng), kind)
        return Step("control", mutate.CONTROL[kind](draft, rng).render(), kind)

    def _timeout_request(self, rng: random.Random) -> Step:
        """D-FUZZ-2: FLOW set-timeout of the stream's write direction, whose receiver is the
        server, to twice its writeInterval and at least SHORTEST_TIMEOUT (D-RCTP-22)."""
        assert self.robot.stream is not None
        interval = self.robot.stream.write_interval or 0.0
        micros = round(max(2 * interval, SHORTEST_TIMEOUT) * 1e6)
        body = encode_flow(TimeoutSet(rng.randrange(1 << 16), Direction.WRITE, micros))
        datagram = push_datagram(rng.randrange(1 << 16), 0, 0, [(int(PayloadType.FLOW), body, 1)])
        return Step("data", datagram, tagged=True)

    def _datagram(self, rng: random.Random, flow: bool = False, data: bool = False) -> bytes:
        """A valid datagram of the session's stream (stream 1 and tag 0 until sent: the
        executor fills in the session's, `Step.tagged`); a FLOW request when `flow`, whose last
        field (an interval, a timeout) is what the FLOW mutations change; DATA most often when
        `data` (a body's size is what its mutation changes)."""
        body, stream = flow_request(rng)
        kind = int(PayloadType.FLOW)
        data_body = self.robot.stream_body()
        if not flow and data_body is not None and rng.random() < (0.8 if data else 0.4):
            kind, body, stream = int(PayloadType.DATA), data_body, 1
        return push_datagram(rng.randrange(1 << 16), 0, 0, [(kind, body, stream)])


def flow_request(rng: random.Random) -> tuple[bytes, int]:
    """A valid FLOW request's body, and its stream: a set-interval or a set-timeout of stream 1,
    whose last field is what the FLOW mutations change, or a heartbeat, the session's (stream 0,
    D-RCTP-22)."""
    request = rng.randrange(1 << 16)
    direction = rng.choice((Direction.READ, Direction.WRITE))
    flows = [
        (encode_flow(IntervalSet(request, direction, 100_000)), 1),
        (encode_flow(TimeoutSet(request, direction, 10_000_000)), 1),
        (encode_flow(HeartbeatRequest(request, rng.randrange(1 << 64))), 0),
    ]
    return rng.choice(flows)
