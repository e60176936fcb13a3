"""Data-stream packets of RCTP/2.0 (specs/rctp-2.0.md §6, D-RCTP-19 to D-RCTP-22)."""

from __future__ import annotations

import struct
import time

VERSION = 2
MAX_DATAGRAM = 65507
DATA, FLOW = 1, 2
REQUEST, ACK, NACK = 0, 1, 2
HEARTBEAT, GET_INTERVAL, SET_INTERVAL, GET_TIMEOUT, SET_TIMEOUT = 1, 2, 3, 4, 5
READ_DIR, WRITE_DIR = 1, 2
NACK_UNKNOWN_OP, NACK_UNKNOWN_STREAM, NACK_REFUSED, NACK_NOT_PERMITTED, NACK_MALFORMED = (
    1,
    2,
    3,
    4,
    5,
)
U32_MAX = 0xFFFFFFFF

_HEADER = struct.Struct("!BBHIII")
_PAYLOAD = struct.Struct("!BBH")
_NTP_UNIX = 2208988800  # seconds from 1900 to 1970


def ntp_now() -> int:
    """The time now in NTP's 64-bit format; the seconds wrap in 2036 (RFC 4330's era rule)."""
    now = time.time()
    whole = int(now)
    frac = int((now - whole) * 2**32) & U32_MAX
    return (((whole + _NTP_UNIX) & U32_MAX) << 32) | frac


def parse(data: bytes) -> tuple[int, int, list[tuple[int, int, bytes]]] | None:
    """(sequence, tag, payloads) of a packet whose framing holds; None otherwise (dropped)."""
    if len(data) < _HEADER.size + _PAYLOAD.size or len(data) > MAX_DATAGRAM:
        return None
    version, count, seq, tag, _sec, _frac = _HEADER.unpack_from(data)
    if version != VERSION or count == 0:
        return None
    payloads, pos = [], _HEADER.size
    for _ in range(count):
        if pos + _PAYLOAD.size > len(data):
            return None
        ptype, stream, length = _PAYLOAD.unpack_from(data, pos)
        pos += _PAYLOAD.size
        if pos + length > len(data):
            return None
        payloads.append((ptype, stream, data[pos : pos + length]))
        pos += length
    if pos != len(data):
        return None
    return seq, tag, payloads


def build(seq: int, tag: int, payloads: list[tuple[int, int, bytes]]) -> bytes:
    stamp = ntp_now()
    head = _HEADER.pack(VERSION, len(payloads), seq & 0xFFFF, tag, stamp >> 32, stamp & U32_MAX)
    return head + b"".join(_PAYLOAD.pack(t, s, len(b)) + b for t, s, b in payloads)


def is_newer(seq: int, highest: int | None, window: int = 1) -> bool:
    """D-RCTP-21: ahead of the highest seen by 1 to 32,767 modulo 65,536 (RFC 1982)."""
    if highest is None:
        return True
    return window <= (seq - highest) % 65536 <= 32767


def micros(seconds_value: float) -> int:
    """RCML seconds as 32-bit microseconds, rounded; longer than 32 bits means "at least"."""
    return min(U32_MAX, round(seconds_value * 1e6))


def flow_ack(op: int, rid: int, fields: bytes) -> bytes:
    return struct.pack("!BBH", ACK, op, rid) + fields


def flow_nack(op: int, rid: int, reason: int) -> bytes:
    return struct.pack("!BBHB", NACK, op, rid, reason)
