"""Test cases for an RSP local system: the state its scenario reaches, then mutated packets of
the robot's (D-FUZZ-9).

The local system's own packets take it to the state (D-RSP-24), so a case's prefix is the
state's name. Its steps are packets of the robot's, made here from valid ones of a session run
offline between the core's two endpoints, and mutated as D-FUZZ-3 mutates a robot's: in `hello`
the WELCOME (it answers the HELLO in the step's place), after that UPLINKs, ACKs and the BYE.
The played robot fills in the live session's ID, numbering, stamp and last received number
(`rsp_cases.FILLED`) and the HELLO's nonce, but for the field the mutation changed.
"""

from __future__ import annotations

import random

from rcmlconf.fuzz.rsp_cases import packet_kinds, packet_mutated, zeros
from rcmlconf.fuzz.steps import Step, TestCase
from rcmlconf.rsp.codec import PacketType
from rcmlconf.rsp.codec.header import TYPE_AT
from rcmlconf.rsp.layout import NONCE_SIZE
from rcmlconf.rsp.model import DeviceKind, RobotModel
from rcmlconf.rsp.session.local import LocalEndpoint
from rcmlconf.rsp.session.robot import RobotEndpoint

#: D-FUZZ-9's states of a local system, in the order its scenario reaches them.
HELLO, WELCOMED, MEMORY_EVENT = "hello", "welcomed", "memory event taken"
_PEER = ("127.0.0.1", 1)
_REQUESTED = (DeviceKind.SENSOR, DeviceKind.MONITOR, DeviceKind.EVENT, DeviceKind.MEMORY_EVENT)


def offline_packets(model: RobotModel) -> dict[PacketType, list[bytes]]:
    """A robot's valid packets by type, from a session of the core's endpoints without I/O:
    the WELCOME, UPLINKs with every state and one occurrence of each event and memory-event
    device, the ACKs of a command and a memory command, and the BYE."""
    robot = RobotEndpoint(model, random=lambda size: b"\x01" * size)  # a session ID is never 0
    local = LocalEndpoint(model, nonce=bytes(NONCE_SIZE))
    found: dict[PacketType, list[bytes]] = {}
    now = 0.0

    def pump() -> None:
        for data in local.datagrams_to_send(now):
            robot.receive_datagram(data, _PEER, now)
        for data, _ in robot.datagrams_to_send(now):
            if len(data) > TYPE_AT:
                found.setdefault(PacketType(data[TYPE_AT]), []).append(data)
            local.receive_datagram(data, now)

    local.connect(now)
    pump()
    for device in model.devices:
        if device.kind is DeviceKind.MODULE or device.kind in _REQUESTED:
            local.set_active(device.name, True)
        elif device.kind in (DeviceKind.COMMAND, DeviceKind.MEMORY_COMMAND):
            local.issue(device.name, zeros(device))
    for _ in range(6):
        now += model.period
        local.handle_timer(now)
        pump()
        for device in model.devices:
            if device.kind in (DeviceKind.SENSOR, DeviceKind.MONITOR):
                robot.set_state(device.name, zeros(device))
            elif device.kind in (DeviceKind.EVENT, DeviceKind.MEMORY_EVENT):
                robot.occur(device.name, zeros(device))
        robot.handle_timer(now)
        pump()
    robot.close(now)
    pump()
    return found


class LocalCases:
    """Makes test cases for a local system of `model`; `seeds` are robot packets to splice."""

    def __init__(self, model: RobotModel, seeds: list[bytes]) -> None:
        self.model = model
        self.seeds = seeds
        packets = offline_packets(model)
        self.bases = {
            HELLO: packets.get(PacketType.WELCOME, []),
            WELCOMED: [
                *packets.get(PacketType.UPLINK, []),
                *packets.get(PacketType.ACK, []),
                *packets.get(PacketType.BYE, []),
            ],
        }
        if any(d.kind is DeviceKind.MEMORY_EVENT for d in model.devices):
            self.bases[MEMORY_EVENT] = self.bases[WELCOMED]

    @property
    def states(self) -> tuple[str, ...]:
        return tuple(state for state, bases in self.bases.items() if bases)

    def kinds(self, state: str) -> tuple[str, ...]:
        return packet_kinds()

    def make(self, state: str, kind: str, rng: random.Random, count: int = 1) -> TestCase:
        """A case in `state`; in `hello`, one step: the WELCOME's."""
        steps = []
        for index in range(1 if state == HELLO else count):
            chosen = kind if index == 0 else rng.choice(self.kinds(state))
            base = rng.choice(self.bases[state])
            data = packet_mutated(self.model, self.seeds, base, chosen, rng)
            steps.append(Step("data", data, chosen, tagged=True))
        return TestCase(state, (), tuple(steps), tuple(s.kind for s in steps))
