"""Test cases for an RSP robot: a session driven to a state, then mutated datagrams (D-FUZZ-1).

The prefix is the state's name: the runner drives the core's own `LocalEndpoint` there against
the robot (HELLO, WELCOME, then what the state needs), so it stays valid whatever session ID,
numbers and stamps the robot's clock gives. The steps are datagrams made from valid DOWNLINKs
of the same states, made here by an endpoint that is shown a WELCOME of its own; the runner
puts the live session's ID, numbering, stamp and last received number into each step's
header, but for the field its mutation changed (`FILLED`).
"""

from __future__ import annotations

import random
from collections.abc import Callable

from rcmlconf.errors import ProtocolError
from rcmlconf.fuzz import mutate
from rcmlconf.fuzz.steps import Step, TestCase
from rcmlconf.rsp.codec import Encryption, PacketType, Welcome, codec_for
from rcmlconf.rsp.codec.bodies import MapBody, Packet, map_body
from rcmlconf.rsp.codec.header import (
    BUFFER_AT,
    ENCRYPTION_AT,
    LAST_AT,
    MODEL_AT,
    SEQUENCE_AT,
    SESSION_AT,
    TIMESTAMP_AT,
    TYPE_AT,
    VERSION,
    VERSION_AT,
    Header,
)
from rcmlconf.rsp.layout import HEADER_SIZE, NONCE_SIZE
from rcmlconf.rsp.model import Device, DeviceKind, RobotModel
from rcmlconf.rsp.session.local import LocalEndpoint
from rcmlconf.values import Value

#: The states of a session with a robot (D-FUZZ-2), each what the local system has done;
#: "idle": no session yet, and the steps are HELLOs.
IDLE = "idle"
STATES = (IDLE, "welcomed", "effector driven", "module active", "memory command sent")
#: The mutations of a HELLO (D-FUZZ-3): its period, its encryption byte, its model ID, its
#: nonce, its length.
HELLO_KINDS = ("rsp-hello-period", "rsp-encryption", "rsp-model", "rsp-hello-nonce", "rsp-truncate",
               "rsp-trailing", "bytes")  # fmt: skip
#: The header fields the runner fills in, by the mutation kind that leaves each as it made it.
FILLED = {
    "rsp-sequence": (SEQUENCE_AT, 2),
    "rsp-timestamp": (TIMESTAMP_AT, 4),
    "rsp-session": (SESSION_AT, 6),
    "rsp-last-received": (LAST_AT, 2),
}
_SESSION = 1
_MAPPED = frozenset({PacketType.DOWNLINK, PacketType.UPLINK, PacketType.ACK})


def _first(model: RobotModel, kind: DeviceKind) -> Device | None:
    return next((d for d in model.devices if d.kind is kind), None)


def zeros(device: Device) -> dict[str, Value]:
    """Each field of `device` at its zero value (D-RSP-20)."""
    return {f.name: f.zero() for f in device.fields}


def drive(endpoint: LocalEndpoint, model: RobotModel, state: str) -> bool:
    """Tell `endpoint` what `state` needs; False when the model has nothing for it."""
    if state == "welcomed":
        return True
    kind = {
        "effector driven": DeviceKind.EFFECTOR,
        "module active": DeviceKind.MODULE,
        "memory command sent": DeviceKind.MEMORY_COMMAND,
    }[state]
    device = _first(model, kind)
    if device is None:
        return False
    if kind is DeviceKind.EFFECTOR:
        endpoint.write(device.name, zeros(device))
    elif kind is DeviceKind.MODULE:
        endpoint.set_active(device.name, True)
    else:
        endpoint.issue(device.name, zeros(device))
    return True


def _offline_hello(model: RobotModel) -> bytes:
    endpoint = LocalEndpoint(model, nonce=bytes(NONCE_SIZE))
    endpoint.connect(0.0)
    return endpoint.datagrams_to_send(0.0)[0]


def _offline_downlinks(model: RobotModel, state: str) -> list[bytes]:
    """Valid DOWNLINKs of `state`, from an endpoint shown a WELCOME of its own (session 1)."""
    codec = codec_for(model)
    nonce = bytes(NONCE_SIZE)
    endpoint = LocalEndpoint(model, nonce=nonce)
    endpoint.connect(0.0)
    endpoint.datagrams_to_send(0.0)
    header = Header(VERSION, model.model_id, Encryption.NONE, PacketType.WELCOME, 0, 0,
                    _SESSION, 0, model.command_buffers)  # fmt: skip
    welcome = Welcome(nonce, bytes(NONCE_SIZE), round(model.period * 1000))
    endpoint.receive_datagram(codec.push_packet(Packet(header, welcome)), 0.0)
    if not drive(endpoint, model, state):
        return []
    found: list[bytes] = []
    now = 0.0
    for _ in range(4):
        now += model.period
        endpoint.handle_timer(now)
        found += [d for d in endpoint.datagrams_to_send(now) if d[TYPE_AT] == PacketType.DOWNLINK]
    return found


def _header(at: int, size: int, rng: random.Random) -> Callable[[bytes], bytes]:
    def change(data: bytes) -> bytes:
        value = rng.choice(
            (0, 1, (1 << 8 * size) - 1, 1 << (8 * size - 1), rng.randrange(1 << 8 * size))
        )
        return data[:at] + value.to_bytes(size, "big") + data[at + size :]

    return change


class RspCases:
    def __init__(self, model: RobotModel, seeds: list[bytes]) -> None:
        self.model = model
        self.seeds = seeds
        made = {state: _offline_downlinks(model, state) for state in STATES if state != IDLE}
        #: A session only welcomed sends DOWNLINKs only to keep alive: its steps start from
        #: those of the other states.
        every = [data for found in made.values() for data in found]
        self.bases = {IDLE: [_offline_hello(model)]}
        for state, found in made.items():
            if found or state == "welcomed":
                self.bases[state] = found or every

    @property
    def states(self) -> tuple[str, ...]:
        return tuple(self.bases)

    def kinds(self, state: str) -> tuple[str, ...]:
        return HELLO_KINDS if state == IDLE else packet_kinds()

    def make(self, state: str, kind: str, rng: random.Random, count: int = 1) -> TestCase:
        steps = []
        for index in range(count):
            chosen = kind if index == 0 else rng.choice(self.kinds(state))
            steps.append(Step("data", self._mutated(state, chosen, rng), chosen, tagged=True))
        return TestCase(state, (), tuple(steps), tuple(s.kind for s in steps))

    def _mutated(self, state: str, kind: str, rng: random.Random) -> bytes:
        bases = self.bases[state] or [bytes(HEADER_SIZE)]
        return packet_mutated(self.model, self.seeds, rng.choice(bases), kind, rng)


def packet_kinds() -> tuple[str, ...]:
    """The mutations of a packet in a session (D-FUZZ-3), a robot's or a local system's."""
    return (
        "rsp-version", "rsp-model", "rsp-encryption", "rsp-type", *FILLED, "rsp-buffer",
        "rsp-map-bits", "rsp-map-past-model", "rsp-truncate", "rsp-trailing", "rsp-payload",
        "rsp-occurrence-id", "rsp-repeat", "bytes", "splice",
    )  # fmt: skip


def packet_mutated(
    model: RobotModel, seeds: list[bytes], data: bytes, kind: str, rng: random.Random
) -> bytes:
    """`data`, a valid packet of `model`, with the one part `kind` names changed (D-FUZZ-3);
    `seeds`: packets to splice it with."""
    size = model.map_size
    body = HEADER_SIZE
    simple = {
        "rsp-version": (VERSION_AT, 1),
        "rsp-model": (MODEL_AT, 2),
        "rsp-encryption": (ENCRYPTION_AT, 1),
        "rsp-type": (TYPE_AT, 1),
        "rsp-buffer": (BUFFER_AT, 1),
        **FILLED,
    }
    if kind in simple:
        return _header(*simple[kind], rng)(data)
    if kind == "rsp-hello-period":  # the last two bytes of a HELLO without MAC
        period = rng.choice((0, 1, 2, 4, 5, 9, 10, 10000, 10001, 65535))
        return data[:-2] + period.to_bytes(2, "big")
    if kind == "rsp-hello-nonce":
        return (
            data[:body]
            + bytes(rng.randrange(256) for _ in range(NONCE_SIZE))
            + data[body + NONCE_SIZE :]
        )
    if kind == "rsp-map-bits":
        at = body + rng.randrange(max(size, 1))
        return (
            data[:at] + bytes([data[at] ^ (1 << rng.randrange(8))]) + data[at + 1 :]
            if at < len(data)
            else data
        )
    if kind == "rsp-map-past-model":
        padding = 8 * size - len(model.devices)
        if padding <= 0 or len(data) < body + size:
            return data + b"\x00"
        bit = len(model.devices) + rng.randrange(padding)
        at = body + bit // 8
        return data[:at] + bytes([data[at] | (0x80 >> bit % 8)]) + data[at + 1 :]
    if kind == "rsp-truncate":
        return data[: rng.randrange(len(data))]
    if kind == "rsp-trailing":
        return data + bytes(rng.randrange(256) for _ in range(rng.choice((1, 2, 7, 300))))
    if kind == "rsp-payload":  # after the Device Map, or the header where there is none
        start = body + (size if len(data) > TYPE_AT and data[TYPE_AT] in _MAPPED else 0)
        if start >= len(data):
            return data + b"\xff"
        at = rng.randrange(start, len(data))
        return data[:at] + bytes([rng.choice((0, 0xFF, 0x7F, 0x80))]) + data[at + 1 :]
    if kind == "rsp-occurrence-id":
        return _occurrence_id(model, data, rng)
    if kind == "rsp-repeat":
        return data + data[body:]
    if kind == "bytes":
        return mutate.flip_bytes(data, rng)
    seed = rng.choice(seeds) if seeds else data
    return mutate.splice(data, seed, rng)


def filled(data: bytes, kind: str, last: bytes | None, index: int, peer_last: int) -> bytes:
    """A step sent `index` packets after `last`, the sender's newest valid packet: its session
    ID, sequence number and stamp follow `last`'s, its last received number is `peer_last`,
    but for the field `kind` changed (`FILLED`)."""
    if last is None or len(data) < LAST_AT + 2:
        return data
    sequence = (int.from_bytes(last[SEQUENCE_AT : SEQUENCE_AT + 2], "big") + index) % 65536
    stamp = int.from_bytes(last[TIMESTAMP_AT : TIMESTAMP_AT + 4], "big")
    fields = {
        "rsp-sequence": sequence.to_bytes(2, "big"),
        "rsp-timestamp": ((stamp + index) % (1 << 32)).to_bytes(4, "big"),
        "rsp-session": last[SESSION_AT : SESSION_AT + 6],
        "rsp-last-received": peer_last.to_bytes(2, "big"),
    }
    out = bytearray(data)
    for name, (at, size) in FILLED.items():
        if name != kind:
            out[at : at + size] = fields[name]
    return bytes(out)


def _occurrence_id(model: RobotModel, data: bytes, rng: random.Random) -> bytes:
    """One occurrence's ID (or an acknowledged one's) moved to an edge of the ID space: 0, just
    behind, half the space ahead (D-RSP-16's edge of new), the last ID; `data` as it was when
    it holds none."""
    codec = codec_for(model)
    try:
        header, packet_body = codec.pull_packet(data)
    except ProtocolError:
        return data
    if not isinstance(packet_body, MapBody):
        return data
    items = list(packet_body.items)
    with_ids = [index for index, item in enumerate(items) if item.id is not None]
    if not with_ids:
        return data
    index = rng.choice(with_ids)
    space = 1 << (8 * model.id_length)
    given = items[index].id or 0
    half = space // 2
    edges = (0, (given - 1) % space, (given - 2) % space, (given + half) % space,
             (given + half - 1) % space, space - 1)  # fmt: skip
    items[index] = items[index]._replace(id=rng.choice(edges))
    return codec.push_packet(Packet(header, map_body(tuple(items))))
