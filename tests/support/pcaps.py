"""Captures made by hand for the dissector's tests: pcap and pcapng files, link layers, IPv4 and
IPv6 packets with UDP or TCP, written field by field with `struct` (not by rcmlconf's writer,
which the tests use besides), and a helper to dissect bytes."""

from __future__ import annotations

import struct
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

from rcmlconf.dissect import Analysis, Dissector, Options, Record
from rcmlconf.pcap.reader import Capture

Address = tuple[str, int]
TCP_SYN, TCP_ACK, TCP_PSH, TCP_FIN = 0x02, 0x10, 0x08, 0x01


def quad(address: str) -> bytes:
    return bytes(int(part) for part in address.split("."))


def ipv4(
    source: str,
    destination: str,
    protocol: int,
    body: bytes,
    ident: int = 0,
    fragment: int = 0x4000,
) -> bytes:
    """An IPv4 packet; `fragment` is the flags and offset field (DF by default)."""
    return (
        struct.pack(
            "!BBHHHBBH4s4s",
            0x45,
            0,
            20 + len(body),
            ident,
            fragment,
            64,
            protocol,
            0,
            quad(source),
            quad(destination),
        )
        + body
    )


def udp(source: Address, destination: Address, payload: bytes) -> bytes:
    return struct.pack("!HHHH", source[1], destination[1], 8 + len(payload), 0) + payload


def tcp(
    source: Address, destination: Address, seq: int, flags: int, payload: bytes, ack: int = 0
) -> bytes:
    return (
        struct.pack("!HHIIBBHHH", source[1], destination[1], seq, ack, 5 << 4, flags, 65535, 0, 0)
        + payload
    )


def ipv4_udp(source: Address, destination: Address, payload: bytes) -> bytes:
    return ipv4(source[0], destination[0], 17, udp(source, destination, payload))


def ipv4_tcp(source: Address, destination: Address, seq: int, flags: int, payload: bytes) -> bytes:
    return ipv4(source[0], destination[0], 6, tcp(source, destination, seq, flags, payload))


def ipv6_udp(
    source: bytes,
    destination: bytes,
    sport: int,
    dport: int,
    payload: bytes,
    extensions: bytes = b"",
    first: int = 17,
) -> bytes:
    """An IPv6 packet with UDP; `extensions` are extension headers, the first of type `first`."""
    body = extensions + struct.pack("!HHHH", sport, dport, 8 + len(payload), 0) + payload
    return struct.pack("!IHBB16s16s", 6 << 28, len(body), first, 64, source, destination) + body


def ethernet(packet: bytes, vlan: int | None = None) -> bytes:
    ethertype = 0x86DD if packet[0] >> 4 == 6 else 0x0800
    tag = struct.pack("!HH", 0x8100, vlan) if vlan is not None else b""
    return b"\x02" * 6 + b"\x04" * 6 + tag + struct.pack("!H", ethertype) + packet


def sll(packet: bytes) -> bytes:
    protocol = 0x86DD if packet[0] >> 4 == 6 else 0x0800
    return struct.pack("!HHH8sH", 0, 772, 6, b"\0" * 8, protocol) + packet


def sll2(packet: bytes) -> bytes:
    protocol = 0x86DD if packet[0] >> 4 == 6 else 0x0800
    return struct.pack("!HHIHBB8s", protocol, 0, 1, 772, 0, 6, b"\0" * 8) + packet


def null(packet: bytes, order: str = "<") -> bytes:
    family = 24 if packet[0] >> 4 == 6 else 2
    return struct.pack(order + "I", family) + packet


def pcap(
    frames: Iterable[tuple[float, bytes]],
    linktype: int = 101,
    order: str = "<",
    nanoseconds: bool = False,
    snaplen: int = 65535,
    lengths: Sequence[int] | None = None,
) -> bytes:
    """A classic pcap file; `lengths` gives frames' lengths on the wire (default: captured)."""
    magic = 0xA1B23C4D if nanoseconds else 0xA1B2C3D4
    out = [struct.pack(order + "IHHiIII", magic, 2, 4, 0, 0, snaplen, linktype)]
    unit = 1_000_000_000 if nanoseconds else 1_000_000
    for index, (time, frame) in enumerate(frames):
        seconds = int(time)
        fraction = round((time - seconds) * unit)
        length = lengths[index] if lengths is not None else len(frame)
        out.append(struct.pack(order + "IIII", seconds, fraction, len(frame), length) + frame)
    return b"".join(out)


# -- pcapng ----------------------------------------------------------------------------------------


def _block(kind: int, body: bytes, order: str) -> bytes:
    body += b"\0" * (-len(body) % 4)
    total = 12 + len(body)
    return struct.pack(order + "II", kind, total) + body + struct.pack(order + "I", total)


def _option(code: int, value: bytes, order: str) -> bytes:
    return struct.pack(order + "HH", code, len(value)) + value + b"\0" * (-len(value) % 4)


def shb(order: str = "<") -> bytes:
    body = struct.pack(order + "IHHq", 0x1A2B3C4D, 1, 0, -1)
    return _block(0x0A0D0D0A, body, order)


def idb(
    linktype: int,
    order: str = "<",
    tsresol: int | None = None,
    tsoffset: int | None = None,
    snaplen: int = 0,
) -> bytes:
    options = b""
    if tsresol is not None:
        options += _option(9, bytes([tsresol]), order)
    if tsoffset is not None:
        options += _option(14, struct.pack(order + "q", tsoffset), order)
    if options:
        options += _option(0, b"", order)
    return _block(1, struct.pack(order + "HHI", linktype, 0, snaplen) + options, order)


def epb(
    interface: int, stamp: int, frame: bytes, order: str = "<", length: int | None = None
) -> bytes:
    body = (
        struct.pack(
            order + "IIIII",
            interface,
            stamp >> 32,
            stamp & 0xFFFFFFFF,
            len(frame),
            len(frame) if length is None else length,
        )
        + frame
    )
    return _block(6, body, order)


def spb(frame: bytes, order: str = "<") -> bytes:
    return _block(3, struct.pack(order + "I", len(frame)) + frame, order)


def opb(interface: int, stamp: int, frame: bytes, order: str = "<") -> bytes:
    body = (
        struct.pack(
            order + "HHIIII", interface, 0, stamp >> 32, stamp & 0xFFFFFFFF, len(frame), len(frame)
        )
        + frame
    )
    return _block(2, body, order)


def nrb(order: str = "<") -> bytes:
    """A Name Resolution Block (skipped by readers that do not resolve names)."""
    return _block(4, struct.pack(order + "HH", 0, 0), order)


# -- dissecting ------------------------------------------------------------------------------------


@dataclass
class Dissected:
    records: list[Record]
    analysis: Analysis

    def findings(self, rule: str | None = None) -> list[str]:
        return [
            f"{f.severity.value} {f.rule} {f.text}"
            for f in self.analysis.findings
            if rule is None or f.rule == rule
        ]

    def rules(self) -> set[str]:
        return {f.rule for f in self.analysis.findings}


def dissect(data: bytes, options: Options | None = None) -> Dissected:
    records: list[Record] = []
    capture = Capture(data)
    analysis = Dissector(options or Options(), records.append).run(capture)
    return Dissected(records, analysis)


class TcpFlow:
    """One TCP connection's segments, with sequence numbers that follow the bytes (or not)."""

    def __init__(self, client: Address, server: Address, start: float = 1_800_000_000.0) -> None:
        self.client, self.server = client, server
        self.next = {client: 1000, server: 5000}
        self.time = start
        self.frames: list[tuple[float, bytes]] = []

    def handshake(self) -> TcpFlow:
        self._add(self.client, TCP_SYN, b"", self.next[self.client])
        self.next[self.client] += 1
        self._add(self.server, TCP_SYN | TCP_ACK, b"", self.next[self.server])
        self.next[self.server] += 1
        self._add(self.client, TCP_ACK, b"", self.next[self.client])
        return self

    def send(self, side: Address, data: bytes, seq: int | None = None) -> TcpFlow:
        """A segment of `data` from `side`; `seq` None: the next bytes (and they move on)."""
        if seq is None:
            seq = self.next[side]
            self.next[side] += len(data)
        self._add(side, TCP_ACK | TCP_PSH, data, seq)
        return self

    def _add(self, side: Address, flags: int, data: bytes, seq: int) -> None:
        other = self.server if side == self.client else self.client
        self.time += 0.001
        self.frames.append((self.time, ipv4_tcp(side, other, seq & 0xFFFFFFFF, flags, data)))
