"""What the Wireshark tests share: pcap files read and written, the plugins, tshark's runs.

`datagrams` and `tcp_streams` read a classic pcap (Ethernet, as dumpcap records loopback, or raw
IPv4, as `rcmlconf.pcap.writer` writes) independently of tshark, so that the tests can decode the
same bytes with rcmlconf's codecs and compare, message by message, with what the plugin shows.
"""

from __future__ import annotations

import json
import struct
from collections.abc import Iterator
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path

import pytest

from rcmlconf.pcap.writer import Payload, write_pcap
from rcmlconf.wireshark.lua import generate_lua
from rcmlconf.wireshark.tshark import Run, run_tshark, tshark_path
from support.rsp_models import CUBO, EVERY_KIND, robot_model

ROOT = Path(__file__).resolve().parents[2]
CAPTURES = ROOT / "captures"
VECTORS = ROOT / "vectors"

_GLOBAL = struct.Struct("<IHHiIII")
_RECORD = struct.Struct("<IIII")
_ETHERNET, _RAW = 1, 101


def need_tshark() -> None:
    if tshark_path() is None:
        pytest.skip("tshark is not installed (apt-get install tshark)")


@dataclass(frozen=True, slots=True)
class Segment:
    """One TCP segment or UDP datagram of a capture."""

    frame: int
    time: float
    protocol: int
    source: tuple[str, int]
    destination: tuple[str, int]
    payload: bytes
    #: TCP's sequence number and flags; 0 for UDP.
    sequence: int = 0
    flags: int = 0


def segments(path: Path) -> Iterator[Segment]:
    data = path.read_bytes()
    magic, _, _, _, _, _, linktype = _GLOBAL.unpack_from(data)
    assert magic == 0xA1B2C3D4, hex(magic)
    assert linktype in (_ETHERNET, _RAW), linktype
    position, number = _GLOBAL.size, 0
    while position < len(data):
        seconds, micros, length, _ = _RECORD.unpack_from(data, position)
        position += _RECORD.size
        frame = data[position : position + length]
        position += length
        number += 1
        if linktype == _ETHERNET:
            if frame[12:14] != b"\x08\x00":
                continue
            frame = frame[14:]
        if frame[0] >> 4 != 4:
            continue
        header = (frame[0] & 0x0F) * 4
        total = struct.unpack_from("!H", frame, 2)[0]
        protocol = frame[9]
        source = ".".join(str(b) for b in frame[12:16])
        destination = ".".join(str(b) for b in frame[16:20])
        body = frame[header:total]
        if protocol == 17:
            sport, dport = struct.unpack_from("!HH", body)
            yield Segment(
                number, seconds + micros / 1e6, 17, (source, sport), (destination, dport), body[8:]
            )
        elif protocol == 6:
            sport, dport, sequence, _, offset, flags = struct.unpack_from("!HHIIBB", body)
            yield Segment(
                number,
                seconds + micros / 1e6,
                6,
                (source, sport),
                (destination, dport),
                body[(offset >> 4) * 4 :],
                sequence,
                flags,
            )


@dataclass(slots=True)
class Direction:
    """One direction of one TCP connection: its bytes in order, and the frame of each byte."""

    source: tuple[str, int]
    destination: tuple[str, int]
    data: bytearray = field(default_factory=bytearray)
    frames: list[int] = field(default_factory=list)


def tcp_streams(path: Path) -> list[Direction]:
    """Every TCP direction's bytes, in the order the connections and directions first speak.

    Segments of loopback and of the writer come in order without loss: a retransmission (a
    sequence number already seen) is skipped.
    """
    directions: dict[tuple[tuple[str, int], tuple[str, int]], Direction] = {}
    next_sequence: dict[tuple[tuple[str, int], tuple[str, int]], int] = {}
    for segment in segments(path):
        if segment.protocol != 6:
            continue
        key = (segment.source, segment.destination)
        if segment.flags & 0x02:  # SYN: a new connection on these ports
            directions.pop(key, None)
            next_sequence[key] = (segment.sequence + 1) & 0xFFFFFFFF
            continue
        if not segment.payload:
            continue
        expected = next_sequence.get(key)
        if expected is not None and segment.sequence != expected:
            assert (expected - segment.sequence) & 0xFFFFFFFF < 0x80000000, "a hole in TCP"
            continue  # a retransmission
        next_sequence[key] = (segment.sequence + len(segment.payload)) & 0xFFFFFFFF
        direction = directions.setdefault(key, Direction(segment.source, segment.destination))
        direction.data += segment.payload
        direction.frames += [segment.frame] * len(segment.payload)
    return list(directions.values())


# -- plugins and runs ------------------------------------------------------------------------------

PLUGINS: dict[str, Path | None] = {"none": None, "CUBO": CUBO, "every-kind": EVERY_KIND}


@cache
def plugin(directory: Path, name: str) -> Path:
    """The plugin of `rcmlconf wireshark [--model M]` for `name` (a key of PLUGINS)."""
    model_path = PLUGINS[name]
    path = directory / f"rcml-{name}.lua"
    path.write_text(
        generate_lua(robot_model(model_path) if model_path is not None else None),
        encoding="utf-8",
    )
    return path


@cache
def run(pcap: Path, lua: Path) -> Run:
    return run_tshark(pcap, lua)


def udp_pcap(path: Path, datagrams: list[bytes], port: int) -> Path:
    """One datagram a frame, from one client port to `port`."""
    with path.open("wb") as file:
        write_pcap(
            file,
            [
                Payload(1.0 + index / 1000, "udp", ("127.0.0.1", 40000), ("127.0.0.1", port), d)
                for index, d in enumerate(datagrams)
            ],
        )
    return path


def load_json(path: Path) -> dict[str, object]:
    document = json.loads(path.read_text(encoding="utf-8"))
    assert isinstance(document, dict)
    return document
