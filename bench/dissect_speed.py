"""How fast does `rcmlconf dissect` read a capture? (rcmlconf.dissect; issue 8)

A deterministic capture of 1,000,000 UDP datagrams (classic pcap, LINKTYPE_RAW IPv4, as our
pcap writer makes them) is written field by field with `struct`, after one RCTP control
connection that sets the data stream up (CONNECT, SETUP with its Transport, GO), so that the
data stream is found as a user's capture would have it found, by SETUP's ports:

- half RSP: a CUBO session on UDP 7340, each period of 5 ms a DOWNLINK and an UPLINK, the
  `downlink-typical` and `uplink-typical` packets of vectors/rsp/packets.json (36 and 42 bytes)
  with their sequence numbers, timestamps and last-received numbers moving on;
- half the RCTP data stream: the robot's DATA of /drive/wheels (three float32) every 5 ms, the
  client's DATA back, and a heartbeat request and its ACK every 100 periods;
- each datagram 0.2 to 0.7 ms on its way, 1 % of them lost and 0.5 % arriving after their
  flow's next one, by a seeded generator, so that the analysis has jitter, losses and
  reordering to count.

Timed, in one process, the median and the best of --rounds (the machine is shared: the best is
the code's speed, the median also the neighbours'): the summary path (`rcmlconf dissect FILE`:
every summary line written, to /dev/null, then the analysis) and the json path (`--format
json`), each as the command runs them (rcmlconf.cli.dissect's writer and the dissector, without
the process start); both without a model, as a user first runs them. Anchor, measured in the
same run: a plain `struct` loop over the same file that reads each record header and the IPv4
and UDP headers and touches the payload — what any reader of the file must do at least
(anchors.md: about 2,000,000 packets/s). tshark with the exported Lua dissector is the Wireshark
bench's (bench/tshark_speed.py), not this one's.

Goal: >= 150,000 packets/s for the summary and json paths.

    python bench/dissect_speed.py [--packets 1000000] [--rounds 3] [--json] [--keep FILE]
"""

from __future__ import annotations

import argparse
import io
import json
import os
import random
import statistics
import struct
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

from rcmlconf.cli.console import Output
from rcmlconf.cli.dissect import RecordLines
from rcmlconf.dissect import Dissector, Options
from rcmlconf.dissect.output.analysis_json import analysis_json
from rcmlconf.dissect.output.analysis_text import analysis_lines
from rcmlconf.pcap.reader import Capture
from rcmlconf.pcap.writer import Payload, PcapWriter

GOAL = 150_000
ROBOT = ("10.0.0.7", 7340)
LOCAL = ("10.0.0.2", 50000)
SERVER = ("10.0.0.7", 7330)
CLIENT = ("10.0.0.2", 50001)
DATA_SERVER = ("10.0.0.7", 7330)
DATA_CLIENT = ("10.0.0.2", 46000)
TAG = 0x5CA1AB1E
SESSION = 0xA1B2C3D4E5F6
DOWN = bytes.fromhex("0100010004041200005168a1b2c3d4e5f6040e00e7a012000078007601c2fe3e280320df")
UP = bytes.fromhex(
    "0100010005040e00005118a1b2c3d4e5f6041110180018000075ff8c3fc00000c01000003f0000000701"
)
#: The RSP header's sequence number, timestamp and last received sequence number.
_SEQ, _TS, _LAST = struct.Struct(">H"), struct.Struct(">I"), struct.Struct(">H")
_RECORD = struct.Struct("<IIII")
_IP_UDP = struct.Struct("!BBHHHBBH4s4sHHHH")
NTP_UNIX = 2_208_988_800


def _checksum(header: bytes) -> int:
    total = sum(struct.unpack(f"!{len(header) // 2}H", header))
    while total >> 16:
        total = (total & 0xFFFF) + (total >> 16)
    return ~total & 0xFFFF


def _quad(address: str) -> bytes:
    return bytes(int(part) for part in address.split("."))


class _Udp:
    """IPv4 + UDP headers by struct, the IP checksum cached by length (the rest is constant)."""

    def __init__(self, source: tuple[str, int], destination: tuple[str, int]) -> None:
        self.source, self.destination = _quad(source[0]), _quad(destination[0])
        self.ports = source[1], destination[1]
        self._sums: dict[int, int] = {}

    def packet(self, payload: bytes) -> bytes:
        length = 28 + len(payload)
        checksum = self._sums.get(length)
        if checksum is None:
            header = _IP_UDP.pack(
                0x45, 0, length, 0, 0x4000, 64, 17, 0, self.source, self.destination, 0, 0, 0, 0
            )[:20]
            checksum = self._sums[length] = _checksum(header)
        # UDP checksum 0: none (RFC 768), as offloading NICs leave it in captures anyway.
        return (
            _IP_UDP.pack(
                0x45,
                0,
                length,
                0,
                0x4000,
                64,
                17,
                checksum,
                self.source,
                self.destination,
                *self.ports,
                length - 20,
                0,
            )
            + payload
        )


def _ntp(seconds: float) -> int:
    whole = int(seconds)
    return ((whole + NTP_UNIX) << 32) | int((seconds - whole) * (1 << 32))


def _data_packet(sequence: int, stamp: float, body: bytes, stream: int = 1, kind: int = 1) -> bytes:
    return (
        struct.pack(">BBHIQBBH", 2, 1, sequence & 0xFFFF, TAG, _ntp(stamp), kind, stream, len(body))
        + body
    )


def write_capture(path: Path, packets: int, seed: int = 7) -> int:
    """The capture; returns the number of UDP datagrams written."""
    random.seed(seed)
    start = 1_795_000_000.0
    with path.open("wb") as file:
        writer = PcapWriter(file)
        # The control connection: our pcap writer makes its handshake and segments.
        for at, source, destination, text in (
            (start, CLIENT, SERVER, "CONNECT /rover RCTP/2.0\r\nCSeq: 1\r\n\r\n"),
            (
                start + 0.001,
                SERVER,
                CLIENT,
                "RCTP/2.0 200 OK\r\nCSeq: 1\r\nSession: benchbenchbench1;timeout=60\r\n\r\n",
            ),
            (
                start + 0.002,
                CLIENT,
                SERVER,
                "SETUP /drive/wheels RCTP/2.0\r\nCSeq: 2\r\nSession: benchbenchbench1\r\n"
                f"Transport: udp;client_port={DATA_CLIENT[1]};mode=both\r\n\r\n",
            ),
            (
                start + 0.003,
                SERVER,
                CLIENT,
                "RCTP/2.0 200 OK\r\nCSeq: 2\r\nSession: benchbenchbench1\r\nTransport: udp;"
                f"client_port={DATA_CLIENT[1]};server_port={DATA_SERVER[1]};tag={TAG:08x};"
                "mode=both;stream=1\r\n\r\n",
            ),
            (
                start + 0.004,
                CLIENT,
                SERVER,
                "GO /drive/wheels RCTP/2.0\r\nCSeq: 3\r\nSession: benchbenchbench1\r\n\r\n",
            ),
            (
                start + 0.005,
                SERVER,
                CLIENT,
                "RCTP/2.0 200 OK\r\nCSeq: 3\r\nSession: benchbenchbench1\r\n\r\n",
            ),
        ):
            writer.write(Payload(at, "tcp", source, destination, text.encode()))
        down, up = _Udp(LOCAL, ROBOT), _Udp(ROBOT, LOCAL)
        robot_data, client_data = _Udp(DATA_SERVER, DATA_CLIENT), _Udp(DATA_CLIENT, DATA_SERVER)
        wheels = struct.pack(">fff", 0.5, -0.25, 1.25)
        written = 0
        #: Per flow, a datagram held back to arrive after the flow's next one (reordered).
        held: dict[int, bytes] = {}
        records: list[bytes] = []
        quarter = packets // 4
        for step in range(quarter):
            at = start + 0.01 + step * 0.005
            rsp_seq = step & 0xFFFF
            millis = (step * 5) & 0xFFFFFFFF
            downlink = bytearray(DOWN)
            _SEQ.pack_into(downlink, 5, rsp_seq)
            _TS.pack_into(downlink, 7, millis)
            _LAST.pack_into(downlink, 17, (rsp_seq - 1) & 0xFFFF)
            uplink = bytearray(UP)
            _SEQ.pack_into(uplink, 5, rsp_seq)
            _TS.pack_into(uplink, 7, millis + 1)
            _LAST.pack_into(uplink, 17, rsp_seq)
            if step % 100 == 50:
                request = struct.pack(">BBHQ", 0, 1, step & 0xFFFF, _ntp(at))
                ack = struct.pack(
                    ">BBHQQQ", 1, 1, step & 0xFFFF, _ntp(at), _ntp(at + 0.0004), _ntp(at + 0.0005)
                )
                from_client = _data_packet(step + 7, at, request, 0, 2)
                from_robot = _data_packet(step + 11, at + 0.001, ack, 0, 2)
            else:
                from_client = _data_packet(step + 7, at, wheels[:8])
                from_robot = _data_packet(step + 11, at + 0.001, wheels)
            for index, (offset, flow, payload) in enumerate(
                (
                    (0.0, down, bytes(downlink)),
                    (0.0015, up, bytes(uplink)),
                    (0.002, client_data, from_client),
                    (0.003, robot_data, from_robot),
                )
            ):
                draw = random.random()
                if draw < 0.01:
                    continue  # lost
                # Sent at `at + offset` by the sender's clock; a path of 0.2 to 0.7 ms.
                arrival = at + offset + 0.0002 + random.random() * 0.0005
                packet = flow.packet(payload)
                late = held.pop(index, None)
                if draw < 0.015 and late is None:
                    held[index] = packet  # arrives after the flow's next one
                    continue
                records.append(_record(arrival, packet))
                written += 1
                if late is not None:
                    records.append(_record(arrival + 0.0001, late))
                    written += 1
            if len(records) > 4096:
                file.write(b"".join(records))
                records.clear()
        for late in held.values():
            records.append(_record(at + 0.01, late))
            written += 1
        file.write(b"".join(records))
    return written


def _record(stamp: float, packet: bytes) -> bytes:
    seconds = int(stamp)
    return _RECORD.pack(seconds, round((stamp - seconds) * 1e6), len(packet), len(packet)) + packet


# -- the paths timed -------------------------------------------------------------------------------


def run_path(path: Path, output_format: str) -> int:
    """What `rcmlconf dissect [--format json] FILE` does once its arguments are read."""
    with open(os.devnull, "w", encoding="utf-8") as sink, Capture.open(path) as capture:
        output = Output(stdout=sink, stderr=io.StringIO())
        lines = RecordLines(output, output_format, None, False, capture)
        analysis = Dissector(Options(), lines.emit).run(capture)
        lines.flush()
        if output_format == "json":
            lines.json({"analysis": analysis_json(analysis)})
        else:
            for text, style in analysis_lines(analysis):
                output.out.line([(text, style)])
    return sum(analysis.capture.messages.values())


def struct_loop(path: Path) -> int:
    """The anchor: each record header, the IPv4 and UDP headers, the payload's first byte."""
    record = struct.Struct("<IIII").unpack_from
    ip_udp = struct.Struct("!BBHHHBBH4s4sHHHH").unpack_from
    count = 0
    with Capture.open(path) as capture:
        data = capture.data
        size = len(data)
        offset = 24
        while offset < size:
            _, _, captured, _ = record(data, offset)
            start = offset + 16
            fields = ip_udp(data, start)
            if fields[6] == 17:
                count += data[start + 28] >= 0
            offset = start + captured
    return count


def timed(run: Callable[[], int], rounds: int) -> tuple[float, float, int]:
    """The best and the median time of `rounds` runs, and what the run counted."""
    times = []
    count = 0
    for _ in range(rounds):
        begun = time.perf_counter()
        count = run()
        times.append(time.perf_counter() - begun)
    return min(times), statistics.median(times), count


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--packets", type=int, default=1_000_000)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--json", action="store_true", help="print the figures as JSON")
    parser.add_argument("--keep", type=Path, help="write the capture here and keep it")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as directory:
        path = args.keep or Path(directory) / "dissect_speed.pcap"
        datagrams = write_capture(path, args.packets)
        size = path.stat().st_size
        rows = []
        for name, run in (
            ("struct loop (anchor)", lambda: struct_loop(path)),
            ("summary (text)", lambda: run_path(path, "text")),
            ("json", lambda: run_path(path, "json")),
        ):
            best, median, count = timed(run, args.rounds)
            rows.append(
                {
                    "path": name,
                    "seconds": median,
                    "best_seconds": best,
                    "messages": count,
                    "packets_per_s": datagrams / median,
                    "best_packets_per_s": datagrams / best,
                }
            )
    if args.json:
        json.dump(
            {
                "datagrams": datagrams,
                "bytes": size,
                "rounds": args.rounds,
                "goal": GOAL,
                "paths": rows,
            },
            sys.stdout,
            indent=1,
        )
        print()
        return
    print(
        f"rcmlconf dissect: {datagrams:,} datagrams (RSP and the RCTP data stream),"
        f" {size / 1e6:.1f} MB; median and best of {args.rounds} rounds (a shared machine:"
        " the best is the code's speed, the median the machine's mood)"
    )
    anchor = rows[0]["packets_per_s"]
    print(f"{'path':<22} {'seconds':>8} {'packets/s':>11} {'best':>11} {'vs anchor':>10}")
    for row in rows:
        print(
            f"{row['path']:<22} {row['seconds']:>8.2f} {row['packets_per_s']:>11,.0f}"
            f" {row['best_packets_per_s']:>11,.0f} {row['packets_per_s'] / anchor:>9.1%}"
        )
    print(f"goal: >= {GOAL:,} packets/s for the summary and json paths")


if __name__ == "__main__":
    main()
