"""A classic pcap file (LINKTYPE_RAW: each record an IPv4 packet) made from application payloads.

The harness sees its TCP traffic as bytes written and read, not as segments. To give dissectors
(ours, tshark) a capture they read as they would a real one, each TCP flow gets a three-way
handshake before its first payload, sequence and acknowledgement numbers that follow the bytes,
and segments of at most `MSS` bytes; every checksum is computed. UDP datagrams are written as
they are.
"""

from __future__ import annotations

import ipaddress
import struct
from collections.abc import Iterable
from dataclasses import dataclass
from typing import BinaryIO

Address = tuple[str, int]

#: pcap's magic (microsecond stamps), version 2.4, snap length, LINKTYPE_RAW.
_GLOBAL = struct.pack("<IHHiIII", 0xA1B2C3D4, 2, 4, 0, 0, 65535, 101)
MSS = 1460
_SYN, _ACK, _PSH = 0x02, 0x10, 0x08
#: The first sequence number of each side of a flow: fixed, so a capture is reproducible.
_ISN = 1000


@dataclass(frozen=True, slots=True)
class Payload:
    at: float
    transport: str  # "tcp" or "udp"
    source: Address
    destination: Address
    data: bytes


class PcapWriter:
    def __init__(self, file: BinaryIO) -> None:
        self._file = file
        self._file.write(_GLOBAL)
        #: (source, destination) -> next sequence number of that direction.
        self._next: dict[tuple[Address, Address], int] = {}

    def write(self, payload: Payload) -> None:
        if payload.transport == "udp":
            self._record(payload.at, _udp(payload.source, payload.destination, payload.data))
            return
        forward = (payload.source, payload.destination)
        if forward not in self._next:
            self._handshake(payload.at, payload.source, payload.destination)
        data = payload.data
        for start in range(0, max(len(data), 1), MSS):
            chunk = data[start : start + MSS]
            self._segment(payload.at, payload.source, payload.destination, _ACK | _PSH, chunk)

    def _handshake(self, at: float, client: Address, server: Address) -> None:
        """SYN, SYN-ACK, ACK, as if the side that spoke first had opened the connection."""
        self._next[(client, server)] = _ISN
        self._next[(server, client)] = _ISN
        self._segment(at, client, server, _SYN, b"", syn=True)
        self._segment(at, server, client, _SYN | _ACK, b"", syn=True)
        self._segment(at, client, server, _ACK, b"")

    def _segment(
        self,
        at: float,
        source: Address,
        destination: Address,
        flags: int,
        data: bytes,
        syn: bool = False,
    ) -> None:
        seq = self._next[(source, destination)]
        ack = self._next[(destination, source)] if flags & _ACK else 0
        self._next[(source, destination)] = (seq + len(data) + (1 if syn else 0)) & 0xFFFFFFFF
        self._record(at, _tcp(source, destination, seq, ack, flags, data))

    def _record(self, at: float, packet: bytes) -> None:
        seconds = int(at)
        micros = round((at - seconds) * 1_000_000)
        if micros >= 1_000_000:
            seconds, micros = seconds + 1, micros - 1_000_000
        self._file.write(struct.pack("<IIII", seconds, micros, len(packet), len(packet)))
        self._file.write(packet)


def write_pcap(file: BinaryIO, payloads: Iterable[Payload]) -> None:
    writer = PcapWriter(file)
    for payload in payloads:
        writer.write(payload)


def _checksum(data: bytes) -> int:
    if len(data) % 2:
        data += b"\0"
    total: int = sum(struct.unpack(f"!{len(data) // 2}H", data))
    while total >> 16:
        total = (total & 0xFFFF) + (total >> 16)
    return ~total & 0xFFFF


def _ip(source: str, destination: str, protocol: int, body: bytes) -> bytes:
    src, dst = ipaddress.IPv4Address(source).packed, ipaddress.IPv4Address(destination).packed
    header = struct.pack(
        "!BBHHHBBH4s4s", 0x45, 0, 20 + len(body), 0, 0x4000, 64, protocol, 0, src, dst
    )
    return header[:10] + struct.pack("!H", _checksum(header)) + header[12:] + body


def _pseudo(source: str, destination: str, protocol: int, length: int) -> bytes:
    return (
        ipaddress.IPv4Address(source).packed
        + ipaddress.IPv4Address(destination).packed
        + struct.pack("!BBH", 0, protocol, length)
    )


def _udp(source: Address, destination: Address, data: bytes) -> bytes:
    length = 8 + len(data)
    header = struct.pack("!HHHH", source[1], destination[1], length, 0)
    checksum = _checksum(_pseudo(source[0], destination[0], 17, length) + header + data) or 0xFFFF
    return _ip(source[0], destination[0], 17, header[:6] + struct.pack("!H", checksum) + data)


def _tcp(
    source: Address, destination: Address, seq: int, ack: int, flags: int, data: bytes
) -> bytes:
    header = struct.pack(
        "!HHIIBBHHH", source[1], destination[1], seq, ack, 5 << 4, flags, 65535, 0, 0
    )
    checksum = _checksum(_pseudo(source[0], destination[0], 6, 20 + len(data)) + header + data)
    return _ip(
        source[0], destination[0], 6, header[:16] + struct.pack("!H", checksum) + header[18:] + data
    )
