#!/usr/bin/env python3
"""An RSP local system (the simulacrum side of specs/rsp.md) running D-RSP-24's scenario.

main.py --robot HOST:PORT --model FILE [--loop] [--psk-file KEY] [--fault NAME]... [-v]
main.py --list-faults | --list-bugs
(--bug NAME, repeatable, plants a robustness bug for the fuzzer's tests)
"""

from __future__ import annotations

import argparse
import contextlib
import os
import selectors
import signal
import socket
import struct
import sys
import time
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import bugs
from rmodel import Device, Malformed, Model, ModelError, load_model
from wire import (
    ACK,
    AES_256_GCM,
    BYE,
    BYE_CLOSED,
    BYE_SHUTDOWN,
    BYE_TIMEOUT,
    CHACHA20_POLY1305,
    DOWNLINK,
    DUPLICATE,
    HELLO,
    NEWER,
    NO_ENCRYPTION,
    PERIOD,
    REFUSED,
    TOO_OLD,
    TYPE_NAMES,
    UPLINK,
    WELCOME,
    Header,
    IndexEstimator,
    Item,
    ReplayWindow,
    aead_for,
    aead_nonce,
    decode_ack,
    decode_uplink,
    encode_id,
    encode_map,
    hkdf_sha256,
    mac16,
)

FAULTS: dict[str, tuple[str, str]] = {
    "window-65": ("R-RSP-18", "the replay window takes a packet 65 behind the newest"),
    "no-replay-list": (
        "R-RSP-18",
        "a packet seen before is handled again (only newer-ness checked)",
    ),
    "no-session-check": ("R-RSP-18", "packets naming another session ID are taken"),
    "trailing-bytes": ("R-RSP-18", "an UPLINK or ACK with bytes after its payloads is taken"),
    "bool-lenient": (
        "R-RCML-30",
        "a bool byte other than 0x00/0x01 is read as true, not malformed",
    ),
    "late-states": ("R-RSP-19", "the buffer byte and sensor values of a late packet are applied"),
    "seq-from-1": ("R-RSP-14", "the first packet of a session (HELLO) is numbered 1, not 0"),
    "timestamp-epoch": (
        "R-RSP-14",
        "timestamps are wall-clock milliseconds, not since the first packet",
    ),
    "lastrecv-arrival": (
        "R-RSP-15",
        "last received sequence number is the last to arrive, not the newest",
    ),
    "hello-new-nonce": ("R-RSP-41", "each repeated HELLO carries a new nonce"),
    "requests-once": (
        "R-RSP-23",
        "sensor/monitor/event request bits go only in the first DOWNLINK",
    ),
    "command-once": (
        "R-RSP-27",
        "a command is sent once and again only after the RTO, like a memory command",
    ),
    "command-new-id": (
        "R-RSP-24",
        "an unacknowledged command gets a new ID each time it is repeated",
    ),
    "mcmd-early-retransmit": (
        "R-RSP-28",
        "an unacknowledged memory command is sent again every period",
    ),
    "mcmd-pipeline": (
        "R-RSP-29",
        "the next memory command goes before the previous one is acknowledged",
    ),
    "mcmd-ignore-buffer": (
        "R-RSP-32",
        "memory commands are sent without regard to the robot's free buffers",
    ),
    "event-no-dedup": ("R-RSP-25", "every copy of an event is taken (no ID check)"),
    "memevent-ack-new-only": (
        "R-RSP-26",
        "a repeated memory event (already taken) is not acknowledged again",
    ),
    "ack-deferred": (
        "R-RSP-26",
        "memory-event ACKs wait for the next period instead of going at once",
    ),
    "bye-ignored": ("R-RSP-22", "a BYE from the robot does not end the session"),
    "period-once": ("R-RSP-43", "PERIOD is sent once, not in each of the three following periods"),
    "heartbeat-10": (
        "R-RSP-42",
        "with no bit to set, an empty DOWNLINK goes every 10 periods, not 5",
    ),
    "welcome-period-ignored": ("R-RSP-42", "the period WELCOME gives is ignored; HELLO's is kept"),
    "welcome-mac-unchecked": (
        "R-RSP-38",
        "the MAC of a WELCOME of an encrypted session is not checked",
    ),
    "timestamp-from-welcome": (
        "R-RSP-14",
        "the clock restarts at WELCOME: timestamps count from it, not from the first HELLO",
    ),
    "lastrecv-uplink-only": (
        "R-RSP-15",
        "last received sequence number follows the robot's UPLINKs only, not its ACKs or WELCOME",
    ),
    "ack-event-bits": (
        "R-RSP-17",
        "events are acknowledged too: ACKs set event bits, which D-RSP-14 never allows",
    ),
    "id-little-endian": (
        "R-RSP-16",
        "2-byte occurrence IDs in DOWNLINKs are written little-endian (ACKs read big-endian)",
    ),
    "ids-shared-counter": (
        "R-RSP-24",
        "one occurrence counter for all devices, not one per device",
    ),
    "taken-per-kind": (
        "R-RSP-25",
        "the last taken ID is kept per kind (event, memory event), not per device",
    ),
    "rto-no-ceiling": (
        "R-RSP-28",
        "the doubled retransmission timeout is not capped at 2 s (only the first one is)",
    ),
    "period-old-value": (
        "R-RSP-43",
        "PERIOD carries the T in force before the change, not the new one",
    ),
}

SESSION_TIMEOUT = 10.0
RUN_LENGTH = 10.0
HELLO_INTERVAL = 0.25
HELLO_REPEATS = 5
HEARTBEAT_PERIODS = 5
READS_A_WAKEUP = 64


class Stop:
    requested = False


def handle_signal(signum: int, frame: Any) -> None:
    Stop.requested = True


def log(verbose: bool, text: str) -> None:
    if verbose:
        print(f"{time.monotonic():.3f} {text}", file=sys.stderr, flush=True)


class Net:
    """One UDP socket towards the robot, woken by packets and by signals."""

    def __init__(self, robot: tuple[str, int], waker: socket.socket) -> None:
        family, _, _, _, address = socket.getaddrinfo(robot[0], robot[1], type=socket.SOCK_DGRAM)[0]
        self.robot = address
        self.sock = socket.socket(family, socket.SOCK_DGRAM)
        self.sock.setblocking(False)
        self.waker = waker
        self.selector = selectors.DefaultSelector()
        self.selector.register(self.sock, selectors.EVENT_READ)
        self.selector.register(waker, selectors.EVENT_READ)

    def is_robot(self, address: Any) -> bool:
        return tuple(address[:2]) == tuple(self.robot[:2])

    def send(self, data: bytes) -> None:
        with contextlib.suppress(OSError):  # UDP: a packet that cannot go is a lost packet
            self.sock.sendto(data, self.robot)

    def wait(self, deadline: float) -> list[tuple[bytes, Any]]:
        """The datagrams that came before `deadline` (at most a bounded batch)."""
        timeout = max(0.0, deadline - time.monotonic())
        received: list[tuple[bytes, Any]] = []
        for key, _ in self.selector.select(timeout):
            if key.fileobj is self.waker:
                with contextlib.suppress(OSError):
                    self.waker.recv(256)
                continue
            for _ in range(READS_A_WAKEUP):
                try:
                    received.append(self.sock.recvfrom(65536))
                except (BlockingIOError, InterruptedError):
                    break
                except OSError:
                    continue  # an ICMP error reported on the socket
        return received

    def close(self) -> None:
        self.selector.close()
        self.sock.close()


@dataclass
class Occurrence:
    ident: int
    fields: bytes
    sends: int = 0
    first_sent: float = 0.0
    due: float = 0.0


@dataclass
class Outbox:
    """A reliable device's occurrences: waiting to go, and sent but not acknowledged."""

    device: Device
    queue: deque[bytes] = field(default_factory=deque)
    inflight: list[Occurrence] = field(default_factory=list)
    next_id: int = 0


def zero_payload(device: Device) -> bytes:
    out = bytearray()
    for f in device.fields:
        f.encode(f.zero(), out)
    return bytes(out)


class Run:
    """One run of D-RSP-24's scenario: open a session, use the robot, end."""

    def __init__(
        self, model: Model, net: Net, faults: set[str], psk: bytes | None, verbose: bool
    ) -> None:
        self.model = model
        self.net = net
        self.faults = faults
        self.psk = psk
        self.verbose = verbose
        self.lenient = frozenset({"trailing"} if "trailing-bytes" in faults else set()) | frozenset(
            {"bool"} if "bool-lenient" in faults else set()
        )
        self.id_space = 256**model.id_length
        self.ended = False

    # --- packets out ---

    def new_session(self, encryption: int) -> None:
        self.encryption = encryption
        self.session = 0
        self.index = 1 if "seq-from-1" in self.faults else 0
        self.t0: float | None = None
        self.window = ReplayWindow(
            65 if "window-65" in self.faults else 64, "no-replay-list" not in self.faults
        )
        self.estimator = IndexEstimator()
        self.last_arrived = 0
        self.last_uplink = 0  # the lastrecv-uplink-only fault
        self.shared_next_id = 0  # the ids-shared-counter fault
        self.tx: Any = None
        self.rx: Any = None

    def send(self, ptype: int, body: bytes) -> None:
        now = time.monotonic()
        if self.t0 is None:
            self.t0 = now
        if "timestamp-epoch" in self.faults:
            stamp = int(time.time() * 1000) & 0xFFFFFFFF
        else:
            stamp = int((now - self.t0) * 1000) & 0xFFFFFFFF
        newest = self.window.newest or 0
        last = self.last_arrived if "lastrecv-arrival" in self.faults else newest
        if "lastrecv-uplink-only" in self.faults:
            last = self.last_uplink
        header = Header(
            1,
            self.model.model_id,
            self.encryption,
            ptype,
            self.index & 0xFFFF,
            stamp,
            self.session,
            last,
            0,
        ).pack()
        if ptype == HELLO and self.encryption:
            assert self.psk is not None
            body += mac16(self.psk, header + body)
        elif self.encryption:
            body = self.tx.encrypt(aead_nonce(self.index), body, header)
        self.index += 1
        self.net.send(header + body)
        size = len(header) + len(body)
        log(self.verbose, f"-> {TYPE_NAMES[ptype]} seq {(self.index - 1) & 0xFFFF}, {size} bytes")

    # --- opening (D-RSP-12, D-RSP-24 step 1) ---

    def execute(self) -> str:
        """'session', 'refused', 'no answer' or 'stopped'."""
        choices = [NO_ENCRYPTION] + ([AES_256_GCM, CHACHA20_POLY1305] if self.psk else [])
        for n, encryption in enumerate(choices):
            outcome = self.open(encryption)
            if outcome == "welcome":
                self.use()
                return "session"
            if outcome == "refused 2" and n + 1 < len(choices):
                continue
            return (
                "stopped"
                if outcome == "stopped"
                else "no answer"
                if outcome == "no answer"
                else "refused"
            )
        return "refused"

    def open(self, encryption: int) -> str:
        self.new_session(encryption)
        period_ms = min(10000, max(5, round(self.model.period * 1000)))
        self.nonces = [os.urandom(16)]
        for attempt in range(1 + HELLO_REPEATS):
            if attempt and "hello-new-nonce" in self.faults:
                self.nonces.append(os.urandom(16))
            self.send(HELLO, self.nonces[-1] + struct.pack(">H", period_ms))
            deadline = time.monotonic() + HELLO_INTERVAL
            while time.monotonic() < deadline:
                for data, address in self.net.wait(deadline):
                    outcome = self.on_opening_packet(data, address)
                    if outcome:
                        return outcome
                if Stop.requested:
                    return "stopped"
        return "no answer"

    def welcome_fields(self, header: Header, data: bytes) -> tuple[bytes, bytes, int] | None:
        """A WELCOME's client nonce, robot nonce and period, if it is well-formed and ours."""
        body = data[20:]
        if len(body) != 34 + (16 if self.encryption else 0) or header.session == 0:
            return None
        echo, robot_nonce = body[:16], body[16:32]
        (period,) = struct.unpack_from(">H", body, 32)
        if echo not in self.nonces or not 5 <= period <= 10000:
            return None
        if self.encryption and "welcome-mac-unchecked" not in self.faults:
            assert self.psk is not None
            if mac16(self.psk, data[:54]) != body[34:]:
                return None
        return echo, robot_nonce, period

    def on_opening_packet(self, data: bytes, address: Any) -> str | None:
        if not self.net.is_robot(address):
            return None
        try:
            h = Header.unpack(data)
        except Malformed:
            return None
        if h.version != 1 or h.model_id != self.model.model_id or h.encryption != self.encryption:
            return None
        if h.type == REFUSED:
            if h.session != 0 or len(data) != 21 or not 1 <= data[20] <= 4:
                return None
            log(self.verbose, f"<- REFUSED {data[20]}")
            return f"refused {data[20]}"
        if h.type != WELCOME:
            return None
        fields = self.welcome_fields(h, data)
        if fields is None:
            return None
        echo, robot_nonce, period = fields
        self.session = h.session
        if "timestamp-from-welcome" in self.faults:
            self.t0 = time.monotonic()
        self.window.take(h.seq)
        self.estimator.update(h.seq)
        self.last_arrived = h.seq
        self.free_buffers = h.buffer
        if bugs.on("welcome-buffer-crash"):
            # the bug: one slot per buffer, the robot's count trusted as an index
            slots: list[Occurrence | None] = [None] * self.model.command_buffers
            self.last_slot = slots[h.buffer - 1] if h.buffer else None
        requested = min(10000, max(5, round(self.model.period * 1000)))
        self.period_ms = requested if "welcome-period-ignored" in self.faults else period
        if self.encryption:
            assert self.psk is not None
            salt = echo + robot_nonce
            sid = h.session.to_bytes(6, "big")
            self.tx = aead_for(
                self.encryption, hkdf_sha256(self.psk, salt, b"RSP/1 downlink" + sid)
            )
            self.rx = aead_for(self.encryption, hkdf_sha256(self.psk, salt, b"RSP/1 uplink" + sid))
        log(
            self.verbose,
            f"<- WELCOME session {h.session:012x} T {period} ms, {h.buffer} buffers free",
        )
        return "welcome"

    # --- using the robot (D-RSP-24 steps 2 to 5) ---

    def use(self) -> None:
        now = time.monotonic()
        self.last_rx = now
        self.using = True
        self.downlinks = 0
        self.quiet_ticks = 0
        self.force_downlink = False
        self.period_left = 0
        self.told_ms: int | None = None
        self.deferred_acks: dict[int, bytes] = {}
        self.taken: dict[int | str, int] = {}
        self.values: dict[str, list[Any]] = {}
        self.srtt: float | None = None
        self.rttvar = 0.0
        self.effector_payloads = {
            d.index: zero_payload(d) for d in self.model.devices if d.kind == "effector"
        }
        self.outboxes: dict[int, Outbox] = {}
        command = self.model.first("command")
        if command:
            self.outboxes[command.index] = Outbox(command, deque([zero_payload(command)]))
        memory = self.model.first("memoryCommand")
        if memory:
            queue = deque([zero_payload(memory)] * (self.model.command_buffers + 1))
            self.outboxes[memory.index] = Outbox(memory, queue)
        self.next_tick = now
        end_at = now + RUN_LENGTH
        while True:
            now = time.monotonic()
            if Stop.requested:
                self.send(BYE, bytes([BYE_SHUTDOWN]))
                return
            if now - self.last_rx >= SESSION_TIMEOUT:
                log(self.verbose, "session timeout")
                self.send(BYE, bytes([BYE_TIMEOUT]))
                return
            if now >= end_at:
                self.send(BYE, bytes([BYE_CLOSED]))
                return
            if now >= self.next_tick:
                self.tick(now)
            deadline = min(self.next_tick, end_at, self.last_rx + SESSION_TIMEOUT)
            for data, address in self.net.wait(deadline):
                self.on_packet(data, address)
                if self.ended:
                    return

    @property
    def period(self) -> float:
        return self.period_ms / 1000

    def tick(self, now: float) -> None:
        self.next_tick += self.period
        if self.next_tick <= now:
            self.next_tick = now + self.period
        if self.deferred_acks:
            self.send(ACK, encode_map(self.model, self.deferred_acks))
            self.deferred_acks = {}
        if self.period_left:
            told = self.told_ms or self.period_ms  # the period-old-value fault: the old T
            self.send(PERIOD, struct.pack(">H", told))
            self.period_left -= 1
        items = self.downlink_items(now)
        limit = 10 if "heartbeat-10" in self.faults else HEARTBEAT_PERIODS
        if items or self.force_downlink or self.quiet_ticks + 1 >= limit:
            self.send(DOWNLINK, encode_map(self.model, items))
            self.downlinks += 1
            self.quiet_ticks = 0
            self.force_downlink = False
        else:
            self.quiet_ticks += 1

    def downlink_items(self, now: float) -> dict[int, bytes]:
        items: dict[int, bytes] = {}
        ask = "requests-once" not in self.faults or self.downlinks == 0
        for dev in self.model.devices:
            if self.using:
                if dev.kind == "module":
                    items[dev.index] = b""
                elif dev.kind == "effector":
                    items[dev.index] = self.effector_payloads[dev.index]
                elif dev.kind in ("sensor", "monitor", "event", "memoryEvent") and ask:
                    items[dev.index] = b""
            box = self.outboxes.get(dev.index)
            if box is not None:
                payload = (
                    self.next_command(box, now)
                    if dev.kind == "command"
                    else self.next_memory(box, now)
                )
                if payload is not None:
                    items[dev.index] = payload
        return items

    def new_occurrence(self, box: Outbox) -> Occurrence:
        if "ids-shared-counter" in self.faults:
            box.next_id = self.shared_next_id
            self.shared_next_id = (self.shared_next_id + 1) % self.id_space
        occurrence = Occurrence(box.next_id, box.queue.popleft())
        box.next_id = (box.next_id + 1) % self.id_space
        box.inflight.append(occurrence)
        return occurrence

    def transmit(self, occurrence: Occurrence, now: float) -> bytes:
        occurrence.sends += 1
        if occurrence.sends == 1:
            occurrence.first_sent = now
        occurrence.due = now + self.rto(occurrence.sends)
        if "id-little-endian" in self.faults:
            ident = occurrence.ident.to_bytes(self.model.id_length, "little")
            return ident + occurrence.fields
        return encode_id(self.model, occurrence.ident) + occurrence.fields

    def next_command(self, box: Outbox, now: float) -> bytes | None:
        """D-RSP-17: a command in every DOWNLINK until its ACK, one at a time per device."""
        if not box.inflight and box.queue:
            self.new_occurrence(box)
        if not box.inflight:
            return None
        occurrence = box.inflight[0]
        if occurrence.sends and "command-once" in self.faults and now < occurrence.due:
            return None
        if occurrence.sends and "command-new-id" in self.faults:
            occurrence.ident = box.next_id
            box.next_id = (box.next_id + 1) % self.id_space
        return self.transmit(occurrence, now)

    def next_memory(self, box: Outbox, now: float) -> bytes | None:
        """D-RSP-17 and D-RSP-19: once, again after each RTO, only while a buffer is free."""
        for occurrence in box.inflight:
            if now >= occurrence.due:
                return self.transmit(occurrence, now)
        unacknowledged = sum(
            len(b.inflight) for b in self.outboxes.values() if b.device.kind == "memoryCommand"
        )
        room = self.free_buffers - unacknowledged > 0 or "mcmd-ignore-buffer" in self.faults
        if box.queue and room and (not box.inflight or "mcmd-pipeline" in self.faults):
            return self.transmit(self.new_occurrence(box), now)
        return None

    def rto(self, sends: int) -> float:
        """RFC 6298's timer as D-RSP-17 bounds it, doubled after each retransmission."""
        if "mcmd-early-retransmit" in self.faults:
            return self.period
        ceiling = max(2.0, 2 * self.period)
        base = 10 * self.period if self.srtt is None else self.srtt + 4 * self.rttvar
        base = min(max(base, 2 * self.period), ceiling)
        if "rto-no-ceiling" in self.faults:
            return base * 2 ** (sends - 1)
        return min(base * 2 ** (sends - 1), ceiling)

    def sample(self, rtt: float) -> None:
        if self.srtt is None:
            self.srtt, self.rttvar = rtt, rtt / 2
        else:
            self.rttvar = 0.75 * self.rttvar + 0.25 * abs(self.srtt - rtt)
            self.srtt = 0.875 * self.srtt + 0.125 * rtt

    # --- packets in ---

    def on_packet(self, data: bytes, address: Any) -> None:
        if not self.net.is_robot(address):
            return
        try:
            h = Header.unpack(data)
        except Malformed:
            return
        if h.version != 1 or h.model_id != self.model.model_id or h.encryption != self.encryption:
            return
        if h.session != self.session and "no-session-check" not in self.faults:
            return
        if h.type not in (WELCOME, UPLINK, ACK, BYE):
            return
        verdict = self.window.check(h.seq)
        if verdict in (DUPLICATE, TOO_OLD):
            return
        body = data[20:]
        index = h.seq
        if self.encryption and h.type != WELCOME:
            index = self.estimator.estimate(h.seq)
            try:
                body = self.rx.decrypt(aead_nonce(index), body, data[:20])
            except Exception:
                return  # fails authentication
        items: list[Item] = []
        try:
            if h.type == UPLINK:
                items = decode_uplink(self.model, body, self.lenient)
            elif h.type == ACK:
                items = decode_ack(self.model, body, self.lenient)
            elif h.type == BYE:
                if bugs.on("bye-reason-crash") and len(body) == 1:
                    # the bug: the reason is named before it is checked
                    log(self.verbose, f"<- BYE ({('closed', 'timeout', 'shutdown')[body[0]]})")
                if len(body) != 1 or body[0] > 2:
                    raise Malformed("BYE reason")
            elif self.welcome_fields(h, data) is None:
                raise Malformed("WELCOME")
        except Malformed as exc:
            log(self.verbose, f"dropped a malformed {TYPE_NAMES[h.type]}: {exc}")
            return
        now = time.monotonic()
        self.window.take(h.seq)
        if self.encryption and h.type != WELCOME:
            self.estimator.update(index)
        self.last_arrived = h.seq
        self.last_rx = now
        if h.type == UPLINK and verdict == NEWER:
            self.last_uplink = h.seq
        newer = verdict == NEWER or "late-states" in self.faults
        if newer:
            self.free_buffers = h.buffer
        if h.type == BYE:
            log(self.verbose, f"<- BYE {body[0]}")
            self.ended = "bye-ignored" not in self.faults
        elif h.type == ACK:
            self.on_ack(items, now)
        elif h.type == UPLINK:
            self.on_uplink(items, newer, now)

    def on_ack(self, items: list[Item], now: float) -> None:
        for item in items:
            box = self.outboxes.get(item.device)
            if box is None:
                continue  # acknowledges nothing this side sends: ignored (D-RSP-17)
            if bugs.on("future-ack-leak") and item.ident is not None:
                ahead = (item.ident - box.next_id) % self.id_space
                if ahead < self.id_space // 2:  # the bug: kept for an occurrence to come
                    bugs.leak(item.ident.to_bytes(4, "big"))
            for occurrence in box.inflight:
                if occurrence.ident == item.ident:
                    box.inflight.remove(occurrence)
                    if occurrence.sends == 1:
                        self.sample(now - occurrence.first_sent)
                    log(self.verbose, f"<- ACK {box.device.name} #{item.ident}")
                    break

    def take(self, item: Item) -> bool:
        """D-RSP-16: an occurrence is new when its ID is 1 to half the ID space ahead."""
        key: int | str = item.device
        if "taken-per-kind" in self.faults:
            key = self.model.devices[item.device].kind
        last = self.taken.get(key)
        assert item.ident is not None
        if last is not None and not 1 <= (item.ident - last) % self.id_space <= self.id_space // 2:
            return False
        self.taken[key] = item.ident
        return True

    def on_uplink(self, items: list[Item], newer: bool, now: float) -> None:
        acks: dict[int, bytes] = {}
        idle = 0
        for item in items:
            dev = self.model.devices[item.device]
            if dev.kind in ("sensor", "monitor"):
                if newer:
                    self.values[dev.name] = item.values
            elif dev.kind == "event":
                if "ack-event-bits" in self.faults:  # "every occurrence is acknowledged"
                    acks[item.device] = encode_id(self.model, item.ident or 0)
                if self.take(item) or "event-no-dedup" in self.faults:
                    log(self.verbose, f"<- event {dev.name} #{item.ident} {item.values}")
                    self.echo()
            elif dev.kind == "memoryEvent":
                last = self.taken.get(item.device)
                new = self.take(item)
                if bugs.on("old-memory-event-hang") and not new and item.ident != last:
                    bugs.hang()  # the bug: the taken IDs are searched for it, one by one
                if new or "memevent-ack-new-only" not in self.faults:
                    acks[item.device] = encode_id(self.model, item.ident or 0)
                if new:
                    log(self.verbose, f"<- memory event {dev.name} #{item.ident} {item.values}")
                    idle += 1
        if acks:
            if "ack-deferred" in self.faults:
                self.deferred_acks.update(acks)
            else:
                self.send(ACK, encode_map(self.model, acks))
        for _ in range(idle):
            self.go_idle(now)

    def echo(self) -> None:
        """D-RSP-24 step 3: one more command of the first command device."""
        command = self.model.first("command")
        if command is not None:
            self.outboxes[command.index].queue.append(zero_payload(command))

    def go_idle(self, now: float) -> None:
        """D-RSP-24 step 4: stop using the robot and double T, told with PERIOD."""
        self.using = False
        self.told_ms = self.period_ms if "period-old-value" in self.faults else None
        self.period_ms = min(2 * self.period_ms, 10000)
        self.period_left = 1 if "period-once" in self.faults else 3
        self.next_tick = now
        self.force_downlink = True
        log(self.verbose, f"idle: T {self.period_ms} ms")


def parse_robot(text: str) -> tuple[str, int]:
    if text.startswith("["):
        host, _, rest = text[1:].partition("]")
        port = rest[1:] if rest.startswith(":") else ""
    else:
        host, _, port = text.rpartition(":") if ":" in text else (text, "", "")
    if not port:
        return host, 7340
    if not port.isdigit() or not 1 <= int(port) <= 65535:
        raise ValueError(f"bad port in {text!r}")
    return host, int(port)


def read_psk(path: str) -> bytes:
    raw = Path(path).read_bytes()
    if len(raw) == 32:
        return raw
    text = raw.decode("ascii", "replace").strip()
    try:
        key = bytes.fromhex(text)
    except ValueError:
        key = b""
    if len(key) != 32:
        raise ValueError("a key file holds 32 bytes, raw or as 64 hexadecimal digits")
    return key


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="An RSP local system running D-RSP-24's scenario.")
    parser.add_argument("--robot", metavar="HOST:PORT", help="the robot (port 7340 by default)")
    parser.add_argument("--model", metavar="FILE", help="the robot model (.rmodel)")
    parser.add_argument(
        "--loop", action="store_true", help="run the scenario again and again until a signal"
    )
    parser.add_argument(
        "--psk-file", metavar="KEY", help="the robot's pre-shared key (32 bytes, raw or hex)"
    )
    parser.add_argument(
        "--fault", action="append", default=[], metavar="NAME", help="misbehave (--list-faults)"
    )
    parser.add_argument("--list-faults", action="store_true", help="print the faults and exit")
    parser.add_argument(
        "--bug",
        action="append",
        default=[],
        metavar="NAME",
        help="plant a robustness bug, for the fuzzer's tests (see --list-bugs)",
    )
    parser.add_argument("--list-bugs", action="store_true", help="print the planted bugs and exit")
    parser.add_argument(
        "-v", "--verbose", action="store_true", help="log packets to standard error"
    )
    args = parser.parse_args(argv)
    if args.list_faults:
        for name, (rid, text) in FAULTS.items():
            print(f"{name}\t{rid}\t{text}")
        return 0
    unknown = [b for b in args.bug if b not in bugs.BUGS]
    if unknown:
        parser.error(f"unknown bug {', '.join(unknown)} (see --list-bugs)")
    if args.list_bugs:
        print(bugs.listing(), end="")
        return 0
    bugs.active = set(args.bug)
    if not args.robot or not args.model:
        parser.error("--robot and --model are required")
    unknown = [f for f in args.fault if f not in FAULTS]
    if unknown:
        parser.error(f"unknown fault {', '.join(unknown)} (see --list-faults)")
    try:
        robot = parse_robot(args.robot)
        model = load_model(args.model)
        psk = read_psk(args.psk_file) if args.psk_file else None
    except (ModelError, ValueError, OSError) as exc:
        print(f"main.py: {exc}", file=sys.stderr)
        return 2
    waker, wake_writer = socket.socketpair()
    waker.setblocking(False)
    wake_writer.setblocking(False)
    signal.set_wakeup_fd(wake_writer.fileno(), warn_on_full_buffer=False)
    signal.signal(signal.SIGINT, handle_signal)
    signal.signal(signal.SIGTERM, handle_signal)
    opened = False
    while not Stop.requested:
        try:
            net = Net(robot, waker)
        except OSError as exc:
            print(f"main.py: {exc}", file=sys.stderr)
            return 1
        try:
            outcome = Run(model, net, set(args.fault), psk, args.verbose).execute()
        finally:
            net.close()
        log(args.verbose, f"run: {outcome}")
        opened = opened or outcome == "session"
        if not args.loop:
            return 0 if opened or outcome == "stopped" else 1
        pause_until = time.monotonic() + (0.05 if outcome == "session" else 0.3)
        while not Stop.requested and time.monotonic() < pause_until:
            time.sleep(0.01)
    return 0


if __name__ == "__main__":
    sys.exit(main())
