"""The robot side of RSP (specs/rsp.md), without I/O: datagrams and a clock in, datagrams out.

`Robot.on_datagram(data, address, now)` and `Robot.on_timer(now)` return the datagrams to send;
`Robot.deadline()` says when `on_timer` wants to run next. One session at a time (D-RSP-12).
"""

from __future__ import annotations

import math
import secrets
import sys
from collections import deque
from dataclasses import dataclass, field
from typing import Any

import bugs
from rmodel import (
    COMMAND,
    EFFECTOR,
    EVENT,
    MEMORY_COMMAND,
    MEMORY_EVENT,
    MODULE,
    MONITOR,
    SENSOR,
    Device,
    Malformed,
    Model,
    clamp_values,
    decode_fields,
    encode_fields,
    zero_values,
)
from wire import (
    ACK,
    BYE,
    BYE_SHUTDOWN,
    BYE_TIMEOUT,
    DOWNLINK,
    HELLO,
    MAC_LENGTH,
    MAX_PERIOD_MS,
    MIN_PERIOD_MS,
    NO_MODEL,
    NONCE_LENGTH,
    NONE,
    PERIOD,
    REFUSED,
    REFUSED_BUSY,
    REFUSED_ENCRYPTION,
    REFUSED_NOT_AUTHENTICATED,
    REFUSED_UNKNOWN_MODEL,
    TYPE_NAMES,
    UPLINK,
    VERSION,
    WELCOME,
    WINDOW,
    Cipher,
    Header,
    ReplayWindow,
    derive_key,
    mac,
    serial_delta,
)

Address = tuple[str, int]
Values = tuple[tuple[Any, ...], ...]
Out = list[tuple[bytes, Address]]

SESSION_TIMEOUT = 10.0  # seconds of silence before BYE (D-RSP-13)
LOSS_PERIODS = 25  # periods of silence before the link is lost
IDLE_PERIODS = 5  # an empty UPLINK every 5 periods when nothing is to be sent
EVENT_UPLINKS = 3  # an event rides the three UPLINKs after it occurs (D-RSP-17)
RTO_MAX = 2.0
MAX_PENDING = 16  # memory events raised and not yet acknowledged, per device
MIN_MOTION = 0.25  # a memory command (a waypoint) takes at least this long, in seconds
WHEELBASE = 220.0  # mm, between the tracks

# Each fault: name -> (requirement broken, description). --list-faults prints this table.
FAULTS: dict[str, tuple[str, str]] = {
    "replay-window-65": (
        "R-RSP-18",
        "a packet 65 behind the newest is still taken (window 1 too long)",
    ),
    "stale-states": (
        "R-RSP-19",
        "effector values, requests, modules and Clear Buffer of a late packet are applied",
    ),
    "model-low-byte": ("R-RSP-21", "only the low byte of a HELLO's model ID is compared"),
    "seq-from-1": ("R-RSP-14", "the robot numbers its packets of a session from 1, not 0"),
    "uptime-timestamp": ("R-RSP-14", "timestamps count from the robot's start, not the session's"),
    "last-arrived-seq": (
        "R-RSP-15",
        "last received sequence number is the latest to arrive, not the newest",
    ),
    "no-reack": ("R-RSP-26", "a repeated command or memory command is not acknowledged again"),
    "memcmd-retaken": ("R-RSP-25", "a repeated memory command (same ID) is taken again"),
    "rto-no-backoff": (
        "R-RSP-28",
        "the retransmission timeout is not doubled after a retransmission",
    ),
    "memevt-no-wait": (
        "R-RSP-29",
        "the next memory event goes before the previous one is acknowledged",
    ),
    "event-twice": ("R-RSP-30", "an event rides two UPLINKs, not three"),
    "ack-when-full": (
        "R-RSP-31",
        "a memory command that finds the buffer full is acknowledged (and lost)",
    ),
    "clear-after-payloads": (
        "R-RSP-33",
        "Clear Buffer is applied after the packet's memory commands",
    ),
    "loss-timer-units": (
        "R-RSP-36",
        "link-loss time is 25 x T in ms read as seconds: it never fires",
    ),
    "timeout-no-bye": ("R-RSP-22", "a session that times out ends without BYE"),
    "bye-reason-0-only": ("R-RSP-22", "a BYE with reason 1 or 2 is taken as malformed and ignored"),
    "sticky-requests": ("R-RSP-23", "request bits are added to the previous ones, never cleared"),
    "map-padding-unchecked": ("R-RSP-18", "a Device Map with bits past the last device is taken"),
    "port-unchecked": ("R-RSP-18", "session packets are taken from any port of the session's host"),
    "repeat-hello-busy": (
        "R-RSP-41",
        "a repeated HELLO (same nonce) is refused busy, not welcomed",
    ),
    "mac-unchecked": ("R-RSP-38", "the MAC of an encrypted HELLO is not checked"),
    "uplink-key-info": ("R-RSP-37", "the uplink key's HKDF info lacks the session ID"),
    "audio-late-played": ("R-RSP-39", "a speaker fragment older than the last played is played"),
    "array-little-endian": (
        "R-RSP-16",
        "numeric arrays (count > 1) in UPLINK payloads are packed little-endian",
    ),
    "values-queued": (
        "R-RSP-34",
        "effector values are queued and applied one a control period, not collapsed to the newest",
    ),
    "onloss-default-zero": (
        "R-RSP-36",
        "an effector without onLoss is read as onLoss=zero: it stops on loss instead of holding",
    ),
    "audio-state-kept": (
        "R-RSP-40",
        "the audio processor's state outlives the session: the next one starts at the old fragment",
    ),
    "keepalive-6": ("R-RSP-42", "with nothing to report, an empty UPLINK every 6 periods, not 5"),
    "ack-deferred": (
        "R-RSP-26",
        "ACKs wait for the robot's next UPLINK beat instead of going at once",
    ),
    "refused-own-model": (
        "R-RSP-21",
        "REFUSED carries the robot's model ID, not the HELLO's echoed",
    ),
    "resend-new-id": ("R-RSP-24", "a memory event sent again gets the next ID, not its own"),
}


def log(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


@dataclass
class EffectorState:
    device: Device
    target: Values
    ramp_from: Values | None = None  # interpolation start (D-RSP-20), None: at target
    ramp_start: float = 0.0
    last_stamp: int | None = None  # the peer timestamp of its last value
    last_fragment: int | None = None  # audio: the fragment played last
    gaps: int = 0  # audio: fragments never received


@dataclass
class Occurrence:
    id: int
    values: Values
    remaining: int = EVENT_UPLINKS  # events: UPLINKs still to ride
    sent_at: float | None = None  # memory events: last sent
    deadline: float = 0.0  # memory events: when to send again
    sends: int = 0


@dataclass
class Job:
    device: Device
    id: int
    values: Values


@dataclass
class Parsed:
    bits: list[int]
    values: dict[int, Values] = field(default_factory=dict)
    occurrences: list[tuple[int, int, Values]] = field(default_factory=list)


class Robot:
    def __init__(
        self,
        model: Model,
        psk: bytes | None,
        faults: set[str],
        verbose: bool = False,
        now: float = 0.0,
    ) -> None:
        self.model = model
        self.psk = psk
        self.offered = {NONE} | ({1, 2} if psk else set())
        self.faults = faults
        self.verbose = verbose
        self.started = now
        self.session: Session | None = None
        self.audio_states: dict[int, EffectorState] = {}  # for the audio-state-kept fault

    def note(self, message: str) -> None:
        if self.verbose:
            log(message)

    def deadline(self) -> float | None:
        return self.session.deadline() if self.session else None

    def on_timer(self, now: float) -> Out:
        return self.session.tick(now) if self.session else []

    def shutdown(self, now: float) -> Out:
        if not self.session:
            return []
        out = [(self.session.bye(BYE_SHUTDOWN, now), self.session.address)]
        self.end("shutdown")
        return out

    def end(self, why: str) -> None:
        if self.session:
            self.note(f"session {self.session.id:012x} ended: {why}")
        self.session = None

    def free_buffers(self) -> int:
        return self.session.free() if self.session else self.model.command_buffers

    def on_datagram(self, data: bytes, address: Address, now: float) -> Out:
        if len(data) < 20:
            return []
        header = Header.unpack(data)
        if header.version != VERSION:
            return []
        if header.model_id == NO_MODEL:
            # malformed in every packet, a HELLO too: it names no model to refuse (D-RSP-10)
            return []
        if header.type == HELLO:
            return self.on_hello(header, data, address, now)
        if self.session:
            return self.session.on_packet(header, data, address, now)
        return []

    def refuse(self, hello: Header, reason: int, address: Address) -> Out:
        self.note(f"REFUSED {reason} to {address[0]}:{address[1]}")
        model_id = self.model.model_id if "refused-own-model" in self.faults else hello.model_id
        header = Header(VERSION, model_id, hello.encryption, REFUSED, 0, 0, 0, hello.seq, 0)
        header.buffer = self.free_buffers()
        return [(header.pack() + bytes([reason]), address)]

    def on_hello(self, header: Header, data: bytes, address: Address, now: float) -> Out:
        body = data[20:]
        encrypted = header.encryption != NONE
        if header.session_id != 0 or header.encryption > 2:
            return []
        if len(body) != NONCE_LENGTH + 2 + (MAC_LENGTH if encrypted else 0):
            return []
        model_id = self.model.model_id
        if "model-low-byte" in self.faults:
            ours = header.model_id & 0xFF == model_id & 0xFF
        else:
            ours = header.model_id == model_id
        if not ours:
            return self.refuse(header, REFUSED_UNKNOWN_MODEL, address)
        if header.encryption not in self.offered:
            return self.refuse(header, REFUSED_ENCRYPTION, address)
        if encrypted and "mac-unchecked" not in self.faults:
            assert self.psk is not None
            if not secrets.compare_digest(mac(self.psk, data[:-MAC_LENGTH]), body[-MAC_LENGTH:]):
                return self.refuse(header, REFUSED_NOT_AUTHENTICATED, address)
        nonce = body[:NONCE_LENGTH]
        period = int.from_bytes(body[NONCE_LENGTH : NONCE_LENGTH + 2], "big")
        if period > MAX_PERIOD_MS:
            return []  # no T of RSP; no REFUSED reason says so
        if bugs.on("hello-period-crash") and period < MIN_PERIOD_MS:
            # the bug: the pace table divides by the period in steps of 5 ms before raising it
            try:
                _ = 1000 // (period // MIN_PERIOD_MS * MIN_PERIOD_MS)
            except ZeroDivisionError as exc:
                bugs.crash(exc)
        s = self.session
        if s is not None:
            same = s.address == address and s.client_nonce == nonce
            if (
                same
                and s.encryption == header.encryption
                and "repeat-hello-busy" not in self.faults
            ):
                return s.hello_again(header, now)
            return self.refuse(header, REFUSED_BUSY, address)
        session_id = 0
        while session_id == 0:
            session_id = secrets.randbits(48)
        self.session = Session(
            self, address, session_id, header, nonce, max(period, MIN_PERIOD_MS), now
        )
        self.note(
            f"session {session_id:012x} with {address[0]}:{address[1]}, "
            f"T = {self.session.period_ms} ms, encryption {header.encryption}"
        )
        return self.session.hello_again(header, now)


class Session:
    def __init__(
        self,
        robot: Robot,
        address: Address,
        session_id: int,
        hello: Header,
        client_nonce: bytes,
        period_ms: int,
        now: float,
    ) -> None:
        self.robot = robot
        self.model = robot.model
        self.faults = robot.faults
        self.address = address
        self.id = session_id
        self.encryption = hello.encryption
        self.client_nonce = client_nonce
        self.robot_nonce = secrets.token_bytes(NONCE_LENGTH)
        self.welcome_period = period_ms
        # the WELCOME's buffer byte, given again in a repeated WELCOME (D-RSP-12): a new session
        # holds no memory command yet
        self.welcome_buffer = self.model.command_buffers
        self.period_ms = period_ms
        depth = WINDOW + 1 if "replay-window-65" in self.faults else WINDOW
        self.window = ReplayWindow(hello.seq, depth)
        self.last_arrived = hello.seq
        self.next_index = 1 if "seq-from-1" in self.faults else 0
        self.t0 = now
        self.last_heard = now
        self.lost = False
        self.requests: set[int] = set()
        self.active: set[int] = set()
        self.effectors = {
            d.index: EffectorState(d, zero_values(d.fields))
            for d in self.model.devices
            if d.kind == EFFECTOR
        }
        if "audio-state-kept" in self.faults:  # the audio processor's state kept by the robot
            for i, state in self.effectors.items():
                if state.device.audio:
                    self.effectors[i] = robot.audio_states.setdefault(i, state)
        self.queued: dict[int, deque[tuple[Values, int]]] = {}  # the values-queued fault
        self.deferred_acks: list[tuple[int, int]] = []  # the ack-deferred fault
        self.last_taken: dict[int, int] = {}
        self.buffer: deque[Job] = deque()
        self.executing: tuple[Job, float] | None = None
        self.events: dict[int, Occurrence] = {}
        self.pending: dict[int, deque[Occurrence]] = {
            d.index: deque() for d in self.model.devices if d.kind == MEMORY_EVENT
        }
        self.next_id: dict[int, int] = {}
        self.srtt: float | None = None
        self.rttvar = 0.0
        self.rto = self.clamp_rto(10 * self.period)
        self.next_tick = now + self.period
        self.idle_ticks = 0
        self.next_raise: dict[int, float] = {}
        self.simulated_at = now
        self.named = {d.name: d for d in self.model.devices}
        self.little = "array-little-endian" in self.faults
        self.memory_events = [d for d in self.model.devices if d.kind == MEMORY_EVENT]
        self.odometry = [0.0, 0.0, 0.0]
        self.mic_fragment = 0
        self.downlink: Cipher | None = None
        self.uplink: Cipher | None = None
        if self.encryption != NONE:
            assert robot.psk is not None
            sid = session_id.to_bytes(6, "big")
            up_info = b"RSP/1 uplink" + (b"" if "uplink-key-info" in self.faults else sid)
            keys = [
                derive_key(robot.psk, client_nonce, self.robot_nonce, info)
                for info in (b"RSP/1 downlink" + sid, up_info)
            ]
            self.downlink = Cipher(self.encryption, keys[0])
            self.uplink = Cipher(self.encryption, keys[1])

    # --- time -------------------------------------------------------------------------------

    @property
    def period(self) -> float:
        return self.period_ms / 1000

    def clamp_rto(self, value: float) -> float:
        """D-RSP-17's bounds, 2 T to 2 s; the 2 s ceiling wins over the floor (T over 1 s)."""
        return min(RTO_MAX, max(2 * self.period, value))

    def deadline(self) -> float:
        return min(self.next_tick, self.last_heard + SESSION_TIMEOUT)

    # --- sending ----------------------------------------------------------------------------

    def waiting(self) -> int:
        """Memory commands held and not yet executed (D-RSP-19). The one being executed has left
        the buffer; so has the head of the queue when nothing runs (it starts at once, in
        `service`, which runs after a DOWNLINK's memory commands are taken)."""
        starts_now = 1 if self.executing is None and self.buffer else 0
        return len(self.buffer) - starts_now

    def free(self) -> int:
        return max(0, self.model.command_buffers - self.waiting())

    def packet(self, kind: int, body: bytes, now: float, buffer: int | None = None) -> bytes:
        index = self.next_index
        self.next_index += 1
        start = self.robot.started if "uptime-timestamp" in self.faults else self.t0
        last = self.last_arrived if "last-arrived-seq" in self.faults else self.window.newest
        header = Header(
            VERSION,
            self.model.model_id,
            self.encryption,
            kind,
            index,
            int((now - start) * 1000),
            self.id,
            last,
            self.free() if buffer is None else buffer,
        ).pack()
        if self.uplink is not None and kind != WELCOME:
            body = self.uplink.seal(index, header, body)
        elif kind == WELCOME and self.encryption != NONE:
            assert self.robot.psk is not None
            body += mac(self.robot.psk, header + body)
        if self.robot.verbose and kind != UPLINK:
            self.robot.note(f"-> {TYPE_NAMES[kind]} seq {index & 0xFFFF}")
        return header + body

    def hello_again(self, hello: Header, now: float) -> Out:
        """WELCOME, for the HELLO that opened the session or a repeat of it (D-RSP-12)."""
        index = self.window.estimate(hello.seq)
        if self.window.check(index) == "newer":
            self.window.mark(index)
        self.last_arrived = hello.seq
        self.last_heard = now
        body = self.client_nonce + self.robot_nonce + self.welcome_period.to_bytes(2, "big")
        return [(self.packet(WELCOME, body, now, self.welcome_buffer), self.address)]

    def bye(self, reason: int, now: float) -> bytes:
        return self.packet(BYE, bytes([reason]), now)

    def device_map(self, bits: list[int]) -> bytearray:
        out = bytearray(self.model.map_length)
        for i in bits:
            out[i // 8] |= 0x80 >> (i % 8)
        return out

    def ack(self, items: list[tuple[int, int]], now: float) -> bytes:
        items.sort()
        body = self.device_map([i for i, _ in items])
        for _, ident in items:
            body += ident.to_bytes(self.model.id_length, "big")
        return self.packet(ACK, bytes(body), now)

    # --- receiving --------------------------------------------------------------------------

    def on_packet(self, header: Header, data: bytes, address: Address, now: float) -> Out:
        if "port-unchecked" in self.faults:
            if address[0] != self.address[0]:
                return []
        elif address != self.address:
            return []
        if (
            header.session_id != self.id
            or header.model_id != self.model.model_id
            or header.encryption != self.encryption
            or header.type not in (DOWNLINK, ACK, BYE, PERIOD)
        ):
            return []
        index = self.window.estimate(header.seq)
        status = self.window.check(index)
        if status is None:
            return []
        body: bytes | None = data[20:]
        if self.downlink is not None:
            body = self.downlink.open(index, data[:20], data[20:])
            if body is None:
                return []
        assert body is not None
        try:
            if header.type == DOWNLINK:
                parsed = self.parse_map(body, DOWNLINK)
            elif header.type == ACK:
                parsed = self.parse_map(body, ACK)
            elif header.type == BYE:
                reason_limit = 0 if "bye-reason-0-only" in self.faults else 2
                if len(body) != 1 or body[0] > reason_limit:
                    raise Malformed("BYE reason")
            elif (
                len(body) != 2 or not MIN_PERIOD_MS <= int.from_bytes(body, "big") <= MAX_PERIOD_MS
            ):
                raise Malformed("PERIOD")
        except Malformed as exc:
            self.robot.note(f"dropped a malformed {TYPE_NAMES[header.type]}: {exc}")
            return []
        self.window.mark(index)
        self.last_arrived = header.seq
        self.last_heard = now
        self.lost = False
        newer = status == "newer"
        self.service(now)
        if header.type == BYE:
            self.robot.end(f"BYE {body[0]} from the local system")
            return []
        if header.type == PERIOD:
            if newer:
                self.set_period(int.from_bytes(body, "big"), now)
            return []
        if header.type == ACK:
            self.on_ack(parsed, now)
            return []
        return self.on_downlink(header, parsed, newer, now)

    def parse_map(self, body: bytes, kind: int) -> Parsed:
        """The Device Map and its payloads (D-RSP-14); Malformed when they do not fit."""
        devices = self.model.devices
        length = self.model.map_length
        if len(body) < length:
            raise Malformed("Device Map cut short")
        bits = [i for i in range(length * 8) if body[i // 8] & (0x80 >> (i % 8))]
        if bits and bits[-1] >= len(devices) and bugs.on("map-padding-crash"):
            try:  # the bug: the bits are looked up before they are checked
                [devices[i].kind for i in bits]
            except IndexError as exc:
                bugs.crash(exc)
        if bits and bits[-1] >= len(devices):
            if "map-padding-unchecked" not in self.faults:
                raise Malformed("a bit past the last device")
            bits = [i for i in bits if i < len(devices)]
        parsed = Parsed(bits)
        off = length
        id_length = self.model.id_length
        for i in bits:
            device = devices[i]
            if kind == ACK:
                if device.kind not in (COMMAND, MEMORY_COMMAND, MEMORY_EVENT):
                    raise Malformed(f"ACK bit of {device.kind} {device.name}")
                if off + id_length > len(body):
                    raise Malformed("ACK cut short")
                ident = int.from_bytes(body[off : off + id_length], "big")
                parsed.occurrences.append((i, ident, ()))
                off += id_length
            elif device.kind == EFFECTOR:
                values, off = decode_fields(device.fields, body, off)
                parsed.values[i] = clamp_values(device.fields, values)
            elif device.kind in (COMMAND, MEMORY_COMMAND):
                if off + id_length > len(body):
                    raise Malformed("ID cut short")
                ident = int.from_bytes(body[off : off + id_length], "big")
                values, off = decode_fields(device.fields, body, off + id_length)
                parsed.occurrences.append((i, ident, clamp_values(device.fields, values)))
        # trailing-bytes-taken: the bug checks only that the payloads are not cut short
        lax = bugs.on("trailing-bytes-taken") and kind == DOWNLINK and off < len(body)
        if off != len(body) and not lax:
            raise Malformed(f"{len(body) - off} bytes after the payloads")
        return parsed

    @staticmethod
    def far(device: Device, values: Values) -> bool:
        """The bug far-waypoint-leak: an integer field of magnitude 2^30 or more."""
        return any(
            f.numeric and not f.is_float and any(abs(v) >= 2**30 for v in value)
            for f, value in zip(device.fields, values, strict=True)
        )

    def is_new(self, device: Device, ident: int) -> bool:
        last = self.last_taken.get(device.index)
        if last is None:
            return True
        ahead = (ident - last) % self.model.id_space
        if device.kind == MEMORY_COMMAND and "memcmd-retaken" in self.faults:
            return ahead <= self.model.id_space // 2
        return 1 <= ahead <= self.model.id_space // 2

    def on_downlink(self, header: Header, parsed: Parsed, newer: bool, now: float) -> Out:
        # Clear Buffer is in the buffer byte, a state: a late packet's is ignored (D-RSP-15,
        # R-RSP-19); its memory commands are handled as any late occurrence
        clear = (newer or "stale-states" in self.faults) and bool(header.buffer & 0x80)
        clear_first = "clear-after-payloads" not in self.faults
        if clear and clear_first:
            self.clear_buffer()
        acks: list[tuple[int, int]] = []
        far = bugs.on("far-waypoint-leak") and self.took_memory_command()
        for i, ident, values in parsed.occurrences:
            device = self.model.devices[i]
            if far and device.kind == MEMORY_COMMAND and self.far(device, values):
                bugs.leak(repr(values).encode())  # the bug: a path plan cached, never freed
            if not self.is_new(device, ident):
                if "no-reack" not in self.faults:
                    acks.append((i, ident))
                continue
            if device.kind == COMMAND:
                self.last_taken[i] = ident
                self.execute(device, ident, values)
                acks.append((i, ident))
            elif self.free() > 0:
                self.last_taken[i] = ident
                self.buffer.append(Job(device, ident, values))
                self.robot.note(f"took {device.name} #{ident}: {values}")
                acks.append((i, ident))
            elif "ack-when-full" in self.faults:
                acks.append((i, ident))
        if clear and not clear_first:
            self.clear_buffer()
        self.service(now)
        if newer or "stale-states" in self.faults:
            self.apply_states(header, parsed, now)
        if not acks:
            return []
        if "ack-deferred" in self.faults:
            self.deferred_acks += [item for item in acks if item not in self.deferred_acks]
            return []
        return [(self.ack(acks, now), self.address)]

    def apply_states(self, header: Header, parsed: Parsed, now: float) -> None:
        devices = self.model.devices
        was_active = self.active
        self.active = {i for i in parsed.bits if devices[i].kind == MODULE}
        requested = {
            i for i in parsed.bits if devices[i].kind in (SENSOR, MONITOR, EVENT, MEMORY_EVENT)
        }
        if "sticky-requests" in self.faults:
            self.requests |= requested
        else:
            self.requests = requested
        for module in was_active - self.active:  # a module switched off stops its devices
            for state in self.effectors.values():
                if state.device.module == module:
                    self.stop(state)
        for i, values in parsed.values.items():
            if not self.is_active(devices[i]):
                continue
            if "values-queued" in self.faults:
                self.queued.setdefault(i, deque(maxlen=64)).append((values, header.timestamp))
            else:
                self.apply_effector(self.effectors[i], values, header.timestamp, now)

    def apply_effector(self, state: EffectorState, values: Values, stamp: int, now: float) -> None:
        """The motion filter (D-RSP-20) and, for a speaker, the audio processor (D-RSP-22)."""
        device = state.device
        # stamp-jump-hang: the bug's motor driver of a module replays every control period
        # missed since the last value, counting the gap without sign
        gap = (stamp - (state.last_stamp or 0)) % 2**32
        if bugs.on("stamp-jump-hang") and device.module is not None and gap >= 2**24:
            bugs.hang()
        if device.audio:
            fragment = values[0][0]
            if state.last_fragment is not None:
                ahead = serial_delta(fragment, state.last_fragment, 16)
                if ahead <= 0 and not (ahead < 0 and "audio-late-played" in self.faults):
                    return  # late, or the fragment already played
                state.gaps += max(0, ahead - 1)
            state.last_fragment = fragment
            state.target = values
            return
        late_gap = (
            state.last_stamp is not None
            and serial_delta(stamp, state.last_stamp, 32) > 1.5 * self.period_ms
        )
        if device.all_numeric and late_gap:
            state.ramp_from = self.actual(state, now)
            state.ramp_start = now
        else:
            state.ramp_from = None
        state.target = values
        state.last_stamp = stamp

    def actual(self, state: EffectorState, now: float) -> Values:
        """An effector's actual state: its value, or where it is on the way to it."""
        if state.ramp_from is None:
            return state.target
        done = (now - state.ramp_start) / self.period
        if done >= 1:
            state.ramp_from = None
            return state.target
        out = []
        for f, start, end in zip(state.device.fields, state.ramp_from, state.target, strict=True):
            mixed = tuple(a + (b - a) * done for a, b in zip(start, end, strict=True))
            out.append(mixed if f.is_float else tuple(round(v) for v in mixed))
        return tuple(out)

    def stop(self, state: EffectorState) -> None:
        """D-RSP-20's stop: numeric fields of an onLoss=zero effector go to their safe value."""
        if state.device.on_loss != "zero":
            return
        state.ramp_from = None
        state.target = tuple(
            f.zero() if f.numeric else v
            for f, v in zip(state.device.fields, state.target, strict=True)
        )

    def on_ack(self, parsed: Parsed, now: float) -> None:
        for i, ident, _ in parsed.occurrences:
            queue = self.pending.get(i)
            if not queue:
                continue  # nothing of this device outstanding: ignored (D-RSP-17)
            for item in list(queue):
                if item.id == ident and item.sent_at is not None:
                    queue.remove(item)
                    if item.sends == 1:
                        self.measure(now - item.sent_at)
                    self.robot.note(f"memory event {self.model.devices[i].name} #{ident} acked")
                    break

    def measure(self, rtt: float) -> None:
        """RFC 6298 §2, with Karn's rule applied by the caller."""
        if self.srtt is None:
            self.srtt, self.rttvar = rtt, rtt / 2
        else:
            self.rttvar = 0.75 * self.rttvar + 0.25 * abs(self.srtt - rtt)
            self.srtt = 0.875 * self.srtt + 0.125 * rtt
        self.rto = self.clamp_rto(self.srtt + max(0.001, 4 * self.rttvar))

    def set_period(self, period_ms: int, now: float) -> None:
        if period_ms == self.period_ms:
            return
        last_uplink = self.next_tick - self.period
        self.period_ms = period_ms
        self.next_tick = max(now, last_uplink + self.period)
        self.rto = self.clamp_rto(self.rto if self.srtt is not None else 10 * self.period)
        self.robot.note(f"T = {period_ms} ms")

    # --- the robot's body -------------------------------------------------------------------

    def is_active(self, device: Device) -> bool:
        return device.module is None or device.module in self.active

    def reports(self, device: Device) -> bool:
        return device.index in self.requests and self.is_active(device)

    def execute(self, device: Device, ident: int, values: Values) -> None:
        self.robot.note(f"executed {device.name} #{ident}: {values}")

    def clear_buffer(self) -> None:
        """D-RSP-19: the waiting memory commands are dropped unexecuted; the one being executed
        has left the buffer and runs on."""
        self.robot.note(f"Clear Buffer: {len(self.buffer)} dropped")
        self.buffer.clear()
        if bugs.on("clear-buffer-crash") and self.took_memory_command():
            self.buffer = None  # type: ignore[assignment]  # the bug: freed, never made again

    def took_memory_command(self) -> bool:
        return any(self.model.devices[i].kind == MEMORY_COMMAND for i in self.last_taken)

    def service(self, now: float) -> None:
        """Run the memory-command buffer: one job at a time, in the order taken (D-RSP-19).
        A job leaves its buffer when it starts; finishing one raises the model's last memory
        event (waypointReached) if it is requested then."""
        while True:
            if self.executing is not None:
                job, end = self.executing
                if now < end:
                    return
                self.executing = None
                self.robot.note(f"done {job.device.name} #{job.id}")
                done = self.memory_events[-1] if self.memory_events else None
                if done is not None and self.reports(done):
                    self.raise_memory_event(done, self.completion(done, job))
            if not self.buffer:
                return
            job = self.buffer.popleft()
            duration = 0.0
            for f, value in zip(job.device.fields, job.values, strict=True):
                if f.name == "duration" and f.numeric:
                    duration = float(value[0]) / 1000
            self.executing = (job, now + max(MIN_MOTION, duration))

    def completion(self, device: Device, job: Job) -> Values:
        """The values of the memory event that tells a job is done: the job's fields of the
        same name and type, its ID as text for a string, zero for the rest."""
        given = {f.name: (f.type, v) for f, v in zip(job.device.fields, job.values, strict=True)}
        out = []
        for f in device.fields:
            if given.get(f.name, ("", None))[0] == f.type:
                out.append(given[f.name][1])
            elif f.type == "string":
                out.append((f"#{job.id}",) * f.count)
            else:
                out.append(f.zero())
        return tuple(out)

    def raise_memory_event(self, device: Device, values: Values) -> None:
        queue = self.pending[device.index]
        if len(queue) >= MAX_PENDING:
            return
        ident = self.next_id.get(device.index, 0)
        self.next_id[device.index] = (ident + 1) % self.model.id_space
        queue.append(Occurrence(ident, values))

    def raise_event(self, device: Device, values: Values) -> None:
        ident = self.next_id.get(device.index, 0)
        self.next_id[device.index] = (ident + 1) % self.model.id_space
        uplinks = EVENT_UPLINKS - 1 if "event-twice" in self.faults else EVENT_UPLINKS
        self.events[device.index] = Occurrence(ident, values, remaining=uplinks)

    def simulate(self, now: float) -> None:
        """Move the body, and raise the occurrences this robot makes on its own while they are
        requested: each event every 500 ms (or 4 T if longer), the first memory event
        (batteryNotice) every second."""
        dt, self.simulated_at = now - self.simulated_at, now
        left, right = self.named.get("leftTrack"), self.named.get("rightTrack")
        if left is not None and right is not None:
            vl = self.actual(self.effectors[left.index], now)[0][0]
            vr = self.actual(self.effectors[right.index], now)[0][0]
            x, y, heading = self.odometry
            heading = (heading + (vr - vl) / WHEELBASE * dt + math.pi) % (2 * math.pi) - math.pi
            speed = (vl + vr) / 2
            self.odometry = [x + speed * dt * math.cos(heading), y + speed * dt * math.sin(heading)]
            self.odometry.append(heading)
        periodic = [d for d in self.model.devices if d.kind == EVENT] + self.memory_events[:1]
        for device in periodic:
            i = device.index
            if not self.reports(device):
                self.next_raise[i] = now + (0.25 if device.kind == EVENT else 0.5)
            elif now >= self.next_raise.get(i, now) and i not in self.events:
                if device.kind == EVENT:
                    self.raise_event(device, self.sample(device, now))
                    self.next_raise[i] = now + max(0.5, 4 * self.period)
                else:
                    self.raise_memory_event(device, self.sample(device, now))
                    self.next_raise[i] = now + 1.0

    def sample(self, device: Device, now: float) -> Values:
        """A sensor's (or a raised event's) newest value; zero values for one not simulated."""
        t = now - self.t0
        if device.name == "odometry":
            return tuple((v,) for v in self.odometry)
        if device.name == "soil":
            return ((round(40 + 20 * math.sin(t / 5)),), (18.5 + t / 100,))
        if device.audio:  # the microphone: a new fragment every time it is reported
            fragment, self.mic_fragment = self.mic_fragment, (self.mic_fragment + 1) % 65536
            size = min(64, device.fields[1].size)
            wave = bytes(
                128 + round(100 * math.sin((fragment * size + k) / 8)) for k in range(size)
            )
            return ((fragment,), (wave,))
        if device.name == "bumper":
            return ((self.next_id.get(device.index, 0) % 3,), (12.5 + 5 * math.sin(t),))
        if device.name == "batteryNotice":
            percent = max(0, 100 - round(t / 30))
            return ((percent,), (11.1 + percent / 80,))
        return zero_values(device.fields)

    def due_memory_event(self, device: Device, now: float) -> Occurrence | None:
        queue = self.pending[device.index]
        window = list(queue) if "memevt-no-wait" in self.faults else list(queue)[:1]
        for item in window:
            if item.sent_at is None:
                return item
        for item in window:
            if now >= item.deadline:
                return item
        return None

    def uplink_body(self, now: float) -> tuple[list[int], bytes]:
        bits: list[int] = []
        payloads = bytearray()
        id_length = self.model.id_length
        for device in self.model.devices:
            i = device.index
            if device.kind == SENSOR and self.reports(device):
                payloads += encode_fields(device.fields, self.sample(device, now), self.little)
            elif device.kind == MONITOR and self.reports(device):
                assert device.of is not None
                payloads += encode_fields(
                    device.fields, self.actual(self.effectors[device.of], now), self.little
                )
            elif device.kind == EVENT and i in self.events:
                event = self.events[i]
                payloads += event.id.to_bytes(id_length, "big")
                payloads += encode_fields(device.fields, event.values, self.little)
                event.remaining -= 1
                if not event.remaining:
                    del self.events[i]
            elif device.kind == MEMORY_EVENT and (item := self.due_memory_event(device, now)):
                # a retransmission backs the timer off (RFC 6298 §5.5)
                if item.sent_at is not None and "rto-no-backoff" not in self.faults:
                    self.rto = self.clamp_rto(2 * self.rto)
                if item.sent_at is not None and "resend-new-id" in self.faults:
                    item.id = self.next_id.get(i, 0)
                    self.next_id[i] = (item.id + 1) % self.model.id_space
                item.sent_at, item.sends = now, item.sends + 1
                item.deadline = now + self.rto
                payloads += item.id.to_bytes(id_length, "big")
                payloads += encode_fields(device.fields, item.values, self.little)
            else:
                continue
            bits.append(i)
        return bits, bytes(self.device_map(bits) + payloads)

    def tick(self, now: float) -> Out:
        self.service(now)
        silent = now - self.last_heard
        if silent >= SESSION_TIMEOUT:
            bye = self.bye(BYE_TIMEOUT, now)
            self.robot.end("timeout")
            return [] if "timeout-no-bye" in self.faults else [(bye, self.address)]
        if now < self.next_tick:
            return []
        loss_after = LOSS_PERIODS * self.period  # seconds
        if "loss-timer-units" in self.faults:
            loss_after = LOSS_PERIODS * self.period_ms  # milliseconds taken as seconds
        if silent > loss_after and not self.lost:
            self.lost = True
            self.robot.note("link lost: onLoss=zero effectors stop")
        if self.lost:
            for state in self.effectors.values():
                self.stop(state)
        uplinks: Out = []
        if self.deferred_acks:
            uplinks.append((self.ack(self.deferred_acks, now), self.address))
            self.deferred_acks = []
        for i, queue in self.queued.items():  # the values-queued fault: one a control period
            if queue:
                values, stamp = queue.popleft()
                self.apply_effector(self.effectors[i], values, stamp, now)
        self.simulate(now)
        bits, body = self.uplink_body(now)
        self.idle_ticks += 1
        keep_alive = (
            self.idle_ticks > IDLE_PERIODS
            if "keepalive-6" in self.faults
            else (self.idle_ticks >= IDLE_PERIODS)
        )
        if bits or keep_alive:
            self.idle_ticks = 0
            uplinks.append((self.packet(UPLINK, body, now), self.address))
        self.next_tick += self.period
        if self.next_tick <= now:
            self.next_tick = now + self.period
        return uplinks
