"""The RCTP/2.0 data stream without I/O: packets (D-RCTP-19), order (D-RCTP-21), FLOW
bodies (D-RCTP-22) and the clock estimate (D-RCTP-24)."""

from __future__ import annotations

import struct
import time
from collections import OrderedDict
from dataclasses import dataclass

VERSION = 2
MAX_DATAGRAM = 65507
DATA, FLOW = 1, 2
REQUEST, ACK, NACK = 0, 1, 2
HEARTBEAT, GET_INTERVAL, SET_INTERVAL, GET_TIMEOUT, SET_TIMEOUT = 1, 2, 3, 4, 5
READ_DIR, WRITE_DIR = 1, 2
UNKNOWN_OP, UNKNOWN_STREAM, REFUSED, NOT_PERMITTED, MALFORMED = 1, 2, 3, 4, 5
NTP_DELTA = 2208988800  # seconds from 1900 to 1970
MAX_U32 = 0xFFFFFFFF

_HEADER = struct.Struct("!BBHIII")
_PAYLOAD = struct.Struct("!BBH")


def ntp_now(unix_epoch: bool = False) -> int:
    """Now as a 64-bit NTP timestamp (RFC 5905); `unix_epoch` forgets the 1900 origin."""
    ns = time.time_ns()
    secs = ns // 1_000_000_000 + (0 if unix_epoch else NTP_DELTA)
    frac = ((ns % 1_000_000_000) << 32) // 1_000_000_000
    return ((secs & MAX_U32) << 32) | frac


def ntp_to_unix(ts: int) -> float:
    """RFC 4330's era rule: a seconds field whose top bit is 0 counts from 2036."""
    secs, frac = ts >> 32, ts & MAX_U32
    if not secs & 0x80000000:
        secs += 1 << 32
    return secs - NTP_DELTA + frac / 2**32


@dataclass
class Packet:
    seq: int
    tag: int
    timestamp: int
    payloads: list[tuple[int, int, bytes]]


def parse_packet(data: bytes) -> Packet | None:
    """A packet whose framing holds, or None (dropped unread, R-RCTP-42)."""
    if len(data) < _HEADER.size + _PAYLOAD.size or len(data) > MAX_DATAGRAM:
        return None
    version, count, seq, tag, secs, frac = _HEADER.unpack_from(data)
    if version != VERSION or count == 0:
        return None
    off = _HEADER.size
    payloads = []
    for _ in range(count):
        if off + _PAYLOAD.size > len(data):
            return None
        ptype, sid, length = _PAYLOAD.unpack_from(data, off)
        off += _PAYLOAD.size
        if off + length > len(data):
            return None
        payloads.append((ptype, sid, data[off : off + length]))
        off += length
    if off != len(data):
        return None
    return Packet(seq, tag, (secs << 32) | frac, payloads)


def build_packet(
    seq: int,
    tag: int,
    ts: int,
    payloads: list[tuple[int, int, bytes]],
    version: int = VERSION,
    tag_le: bool = False,
) -> bytes:
    """A packet; `version` and `tag_le` (the tag in little-endian order) are for faults."""
    if tag_le:
        tag = int.from_bytes(tag.to_bytes(4, "big"), "little")
    out = bytearray(_HEADER.pack(version, len(payloads), seq, tag, ts >> 32, ts & MAX_U32))
    for ptype, sid, body in payloads:
        out += _PAYLOAD.pack(ptype, sid, len(body)) + body
    return bytes(out)


class Order:
    """D-RCTP-21: the newest sequence number seen from the peer, and what was skipped."""

    def __init__(self, zero_is_newer: bool = False) -> None:
        self.highest: int | None = None
        self.missing: set[int] = set()
        self.received = self.late = self.duplicates = 0
        self._zero_is_newer = zero_is_newer

    def newer(self, seq: int) -> bool:
        self.received += 1
        if self.highest is None:
            self.highest = seq
            return True
        ahead = (seq - self.highest) % 65536
        if 1 <= ahead <= 32767 or (self._zero_is_newer and ahead == 0):
            for k in range(1, min(ahead, 1024)):
                self.missing.add((self.highest + k) % 65536)
            if len(self.missing) > 4096:
                self.missing.clear()
            self.highest = seq
            return True
        if seq in self.missing:
            self.missing.discard(seq)
            self.late += 1
        else:
            self.duplicates += 1
        return False


def flow_body(message: int, op: int, rid: int, fields: bytes = b"") -> bytes:
    return struct.pack("!BBH", message, op, rid) + fields


def nack(op: int, rid: int, reason: int) -> bytes:
    return flow_body(NACK, op, rid, bytes([reason]))


class AnswerCache:
    """The answerer's last 64 answers, by request id (D-RCTP-22)."""

    def __init__(self, size: int = 64) -> None:
        self._answers: OrderedDict[int, tuple[int, bytes]] = OrderedDict()
        self._size = size

    def get(self, rid: int) -> tuple[int, bytes] | None:
        return self._answers.get(rid)

    def put(self, rid: int, sid: int, body: bytes) -> None:
        self._answers[rid] = (sid, body)
        self._answers.move_to_end(rid)
        while len(self._answers) > self._size:
            self._answers.popitem(last=False)


class Clock:
    """NTP's clock filter over the last eight heartbeats (D-RCTP-24)."""

    def __init__(self, precision: float) -> None:
        self.precision = precision
        self.samples: list[tuple[float, float]] = []  # (offset, delay)

    def add(self, t1: float, t2: float, t3: float, t4: float) -> None:
        offset = ((t2 - t1) + (t3 - t4)) / 2
        delay = max(0.0, (t4 - t1) - (t3 - t2))
        self.samples = [*self.samples, (offset, delay)][-8:]

    def estimate(self) -> tuple[float, float] | None:
        """(offset, uncertainty) in seconds: the robot's clock minus ours."""
        if not self.samples:
            return None
        best = self.samples[0]
        for sample in self.samples[1:]:
            if sample[1] <= best[1]:
                best = sample
        return best[0], best[1] / 2 + self.precision


def micros(seconds: float) -> int:
    """RCML's seconds as a 32-bit number of microseconds, saturating (D-RCTP-22)."""
    return min(MAX_U32, round(seconds * 1_000_000))
