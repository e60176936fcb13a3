"""How fast does `rcmlconf fuzz` run test cases against an RSP robot? (issue 29)

The embedded reference robot (CUBO) runs as a process of its own, as `rcmlconf fuzz --model`
starts it. One seeded list of test cases is made with the fuzzer's own generator, then run two
ways against it, in the same run, rounds interleaved (the machine is shared):

- the floor: a bare socket loop. For each case it opens a session (HELLO, the robot's WELCOME),
  sends the case's steps with the header fields the runner fills in (the session's ID, the
  numbering), reads what came within 4 ms of each, and ends the session with BYE: no state
  reached, no periods, no checks. It says how many of its cases got a WELCOME;
- the fuzzer's runner: each case run and judged by the oracles (`RspTarget.run` and `judge`):
  the session driven to the case's state by the core's endpoint, three periods of it before
  the steps and two after (D-FUZZ-2), the dissector over the case's traffic.

Goal: the runner at least 50 % of the floor on RSP datagrams.

    python bench/fuzz_rsp_speed.py [--cases 60] [--rounds 3] [--json]
"""

from __future__ import annotations

import argparse
import json
import random
import socket
import statistics
import time

from rcmlconf.conformance.targets import REFERENCE_RMODEL
from rcmlconf.errors import ProtocolError
from rcmlconf.fuzz.launch import embedded_command, free_port, started
from rcmlconf.fuzz.rsp_cases import FILLED, IDLE, RspCases
from rcmlconf.fuzz.rsp_target import RspTarget
from rcmlconf.fuzz.seeds import rsp_seeds
from rcmlconf.fuzz.steps import Step, TestCase
from rcmlconf.rsp.codec import Bye, ByeReason, PacketType, RspCodec, codec_for
from rcmlconf.rsp.codec.bodies import Packet
from rcmlconf.rsp.codec.header import LAST_AT, SEQUENCE_AT, Header
from rcmlconf.rsp.model import RobotModel
from rcmlconf.rsp.session.local import LocalEndpoint
from rcmlconf.validate.validator import load_robot_model

#: The floor's wait for the robot after each datagram, seconds: the fuzzer's idle drain.
IDLE_WAIT = 0.004


def bare_loop(
    address: tuple[str, int], model: RobotModel, cases: list[TestCase]
) -> tuple[float, int]:
    """The floor: a session, the steps' bytes, a BYE; one read after each, no checks. Also how
    many cases got a WELCOME (the others are refused: a session of theirs is still open)."""
    codec = codec_for(model)
    opened = 0
    start = time.perf_counter()
    for case in cases:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
            sock.connect(address)
            endpoint = LocalEndpoint(model)
            endpoint.connect(0.0)
            for hello in endpoint.datagrams_to_send(0.0):
                sock.send(hello)
            sock.settimeout(1.0)
            try:
                answer = sock.recv(65535)
                welcome = codec.pull_header(answer)
            except (TimeoutError, OSError, ProtocolError):
                continue
            if welcome.type != PacketType.WELCOME:
                continue
            opened += 1
            sock.settimeout(IDLE_WAIT)
            answers = []
            newest = 0
            for index, step in enumerate(case.steps, start=1):
                data = step.data if case.state == IDLE else _filled(step, welcome, index)
                if step.kind == "rsp-sequence" and len(data) > SEQUENCE_AT + 2:
                    newest = max(newest, int.from_bytes(data[SEQUENCE_AT : SEQUENCE_AT + 2]))
                try:
                    sock.send(data)
                    answers.append(sock.recv(65535))
                except (TimeoutError, OSError):
                    pass
            for _ in range(16):  # what is still coming: a HELLO step's WELCOME must get its BYE
                try:
                    answers.append(sock.recv(65535))
                except (TimeoutError, OSError):
                    break
            # BYEs: of the session, numbered past the steps (and past a step's own number),
            # and of each session a HELLO step opened. The robot serves one at a time.
            count = len(case.steps) + 1
            byes = [_bye(codec, welcome, count), _bye(codec, welcome, max(count, newest + 1))]
            for answer in answers:
                try:
                    other = codec.pull_header(answer)
                except ProtocolError:
                    continue
                if other.type == PacketType.WELCOME:
                    byes.append(_bye(codec, other, 1))
            for bye in byes:
                sock.send(bye)
    return time.perf_counter() - start, opened


def _filled(step: Step, welcome: Header, index: int) -> bytes:
    """The step with the session's header fields, as the fuzzer's runner fills them in (but
    the field its mutation changed): the session's ID, number `index`, the robot's last."""
    fields = {
        "rsp-sequence": index.to_bytes(2, "big"),
        "rsp-timestamp": index.to_bytes(4, "big"),
        "rsp-session": welcome.session_id.to_bytes(6, "big"),
        "rsp-last-received": welcome.sequence.to_bytes(2, "big"),
    }
    data = bytearray(step.data)
    if len(data) < LAST_AT + 2:
        return step.data
    for name, (at, size) in FILLED.items():
        if name != step.kind:
            data[at : at + size] = fields[name]
    return bytes(data)


def _bye(codec: RspCodec, welcome: Header, sequence: int) -> bytes:
    """BYE (reason 0) of the session `welcome` opened, numbered `sequence`."""
    header = welcome._replace(
        type=PacketType.BYE, sequence=sequence % 65536, last_received=welcome.sequence, buffer=0
    )
    return codec.push_packet(Packet(header, Bye(ByeReason.CLOSED)))


def runner(target: RspTarget, cases: list[TestCase]) -> float:
    start = time.perf_counter()
    for case in cases:
        target.judge(target.run(case))
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cases", type=int, default=60)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    model = load_robot_model(REFERENCE_RMODEL)
    made = RspCases(model, rsp_seeds(model.model_id))
    rng = random.Random(7)
    cases = []
    for _ in range(args.cases):
        state = rng.choice(made.states)
        cases.append(made.make(state, rng.choice(made.kinds(state)), rng, rng.choice((1, 1, 2, 3))))
    address = ("127.0.0.1", free_port())
    times: dict[str, list[float]] = {"floor": [], "runner": []}
    opened = []
    with started(embedded_command(address[1], (), REFERENCE_RMODEL), address, 10.0, "udp"):
        target = RspTarget(address, model, 5.0)
        for _ in range(args.rounds):
            spent, welcomed = bare_loop(address, model, cases)
            times["floor"].append(spent)
            opened.append(welcomed)
            times["runner"].append(runner(target, cases))
    rates = {name: args.cases / statistics.median(spent) for name, spent in times.items()}
    result = {
        "cases": args.cases,
        "rounds": args.rounds,
        "period_ms": round(model.period * 1000),
        "floor_sessions_opened": min(opened),
        "cases_per_second": {name: round(rate, 1) for name, rate in rates.items()},
        "runner_vs_floor": round(rates["runner"] / rates["floor"], 3),
        "goal_runner_vs_floor": 0.50,
    }
    if args.json:
        print(json.dumps(result, indent=1))
        return
    for name, rate in rates.items():
        print(f"{name:7} {rate:8.1f} cases/s (median of {args.rounds})")
    print(
        f"runner/floor {result['runner_vs_floor']:.2f} (goal >= 0.50);"
        f" the floor opened {min(opened)} of {args.cases} sessions"
    )


if __name__ == "__main__":
    main()
