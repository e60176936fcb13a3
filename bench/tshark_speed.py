"""How fast does tshark read RSP and the RCTP data stream with the generated Lua dissector?

The anchor of `rcmlconf dissect`'s speed (bench/dissect_speed.py measures ours on the same file):
a capture of N datagrams, half RSP (CUBO's typical DOWNLINK and UPLINK, UDP 7340) and half the
RCTP/2.0 data stream (a DATA payload of the rover's wheels, every 50th packet with a heartbeat
request, UDP 7330), written deterministically with `rcmlconf.pcap.writer` — the same N, the same
bytes, run after run — is read by

    tshark -n -r FILE -X lua_script:rcml-cubo.lua -T fields -e rcmlrsp.seq

with a clean WIRESHARK_CONFIG_DIR and the plugin of `rcmlconf wireshark --model cubo.rmodel`.
Printed: packets per second (N / wall time of the tshark process), the median of --rounds, and for
context tshark without the plugin on the same file (`-e udp.srcport`: reading and dissecting up to
UDP, which every Lua dissector pays anyway).

    python bench/tshark_speed.py [--packets 1000000] [--rounds 1] [--pcap FILE] [--json]

`--pcap FILE` keeps the capture (written only if FILE is missing), so that bench/dissect_speed.py
can read the same one. Measured here: see the report of the bench run (the machine is shared).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import struct
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from rcmlconf.pcap.writer import Payload, PcapWriter
from rcmlconf.rctp.datastream.flow import HeartbeatRequest
from rcmlconf.rctp.datastream.packets import DataPayload, FlowPayload, Packet, push_packet
from rcmlconf.rsp.codec import Encryption, Header, Item, MapBody, PacketType, RspCodec
from rcmlconf.rsp.codec import Packet as RspPacket
from rcmlconf.validate.validator import load_robot_model
from rcmlconf.wireshark.lua import generate_lua

ROOT = Path(__file__).resolve().parent.parent
CUBO = ROOT / "rcmlconf" / "reference" / "robots" / "cubo" / "cubo.rmodel"
SESSION = 0xA1B2C3D4E5F6
TAG = 0xA3F19C07
#: Where each kind goes.
LOCAL, ROBOT = ("127.0.0.1", 40000), ("127.0.0.1", 7340)
CLIENT, SERVER = ("127.0.0.1", 40001), ("127.0.0.1", 7330)


def _templates() -> list[tuple[bytes, int, tuple[str, int], tuple[str, int]]]:
    """(datagram, offset of its sequence number, source, destination) of each kind, made with
    rcmlconf's codecs."""
    model = load_robot_model(CUBO)
    codec = RspCodec(model)
    by_name = {d.name: d.position for d in model.devices}

    def rsp(kind: PacketType, items: list[Item]) -> bytes:
        header = Header(1, model.model_id, Encryption.NONE, kind, 0, 0, SESSION, 0, 0)
        return codec.push_packet(RspPacket(header, MapBody(tuple(items))))

    downlink = rsp(
        PacketType.DOWNLINK,
        [
            Item(by_name["base"]),
            Item(by_name["leftWheel"], None, {"speed": 120}),
            Item(by_name["rightWheel"], None, {"speed": 118}),
            Item(by_name["leftWheelMonitor"]),
            Item(by_name["rightWheelMonitor"]),
            Item(by_name["position"]),
        ],
    )
    uplink = rsp(
        PacketType.UPLINK,
        [
            Item(by_name["leftWheelMonitor"], None, {"speed": 120}),
            Item(by_name["rightWheelMonitor"], None, {"speed": 118}),
            Item(by_name["position"], None, {"x": 0.25, "y": -0.5, "heading": 1.5}),
        ],
    )
    wheels = struct.pack(">ff", 0.25, -0.25)
    data = push_packet(Packet(0, TAG, 0xEBE6BF4080000000, (DataPayload(1, wheels),)))
    beat = push_packet(
        Packet(
            0,
            TAG,
            0xEBE6BF4080000000,
            (DataPayload(1, wheels), FlowPayload(0, HeartbeatRequest(7, 0xEBE6BF4080000000))),
        )
    )
    return [
        (downlink, 5, LOCAL, ROBOT),
        (uplink, 5, ROBOT, LOCAL),
        (data, 2, CLIENT, SERVER),
        (beat, 2, CLIENT, SERVER),
    ]


def write_capture(path: Path, packets: int) -> None:
    """N datagrams: RSP DOWNLINK, UPLINK and data-stream DATA in turn, a heartbeat every 50th
    data-stream packet; sequence numbers counting up per sender; 1 ms apart."""
    downlink, uplink, data, beat = _templates()
    sequences = {"down": 0, "up": 0, "ds": 0}
    with path.open("wb") as file:
        writer = PcapWriter(file)
        for number in range(packets):
            turn = number % 4
            if turn == 0:
                template, key = downlink, "down"
            elif turn == 1:
                template, key = uplink, "up"
            else:
                template, key = (beat if number % 100 == 2 else data), "ds"
            datagram = bytearray(template[0])
            struct.pack_into(">H", datagram, template[1], sequences[key] & 0xFFFF)
            sequences[key] += 1
            writer.write(
                Payload(1.0 + number / 1000, "udp", template[2], template[3], bytes(datagram))
            )


def _tshark(pcap: Path, options: list[str]) -> tuple[float, int]:
    tshark = shutil.which("tshark")
    assert tshark is not None
    with tempfile.TemporaryDirectory() as config:
        start = time.perf_counter()
        done = subprocess.run(
            [tshark, "-n", "-r", str(pcap), *options],
            capture_output=True,
            env={**os.environ, "WIRESHARK_CONFIG_DIR": config},
            check=True,
        )
        elapsed = time.perf_counter() - start
    problems = [line for line in done.stderr.decode().splitlines() if "Running as user" not in line]
    if problems:
        raise SystemExit(f"tshark said: {problems[:3]}")
    return elapsed, done.stdout.count(b"\n")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--packets", type=int, default=1_000_000)
    parser.add_argument("--rounds", type=int, default=1)
    parser.add_argument("--pcap", type=Path, help="keep the capture here (reused if it exists)")
    parser.add_argument("--json", action="store_true")
    options = parser.parse_args()
    if shutil.which("tshark") is None:
        raise SystemExit("tshark_speed.py: tshark is not installed (apt-get install tshark)")
    with tempfile.TemporaryDirectory(prefix="rcmlconf-tshark-speed-") as work:
        pcap = options.pcap or Path(work) / "capture.pcap"
        if not pcap.exists():
            start = time.perf_counter()
            write_capture(pcap, options.packets)
            print(
                f"wrote {pcap}: {options.packets:,} packets, {pcap.stat().st_size:,} bytes"
                f" in {time.perf_counter() - start:.1f} s",
                file=sys.stderr,
            )
        lua = Path(work) / "rcml-cubo.lua"
        lua.write_text(generate_lua(load_robot_model(CUBO)), encoding="utf-8")
        plugin_runs, plain_runs = [], []
        for _ in range(options.rounds):
            elapsed, lines = _tshark(
                pcap, ["-X", f"lua_script:{lua}", "-T", "fields", "-e", "rcmlrsp.seq"]
            )
            assert lines == options.packets or options.pcap, (lines, options.packets)
            plugin_runs.append(lines / elapsed)
            elapsed, lines = _tshark(pcap, ["-T", "fields", "-e", "udp.srcport"])
            plain_runs.append(lines / elapsed)
    result = {
        "packets": lines,
        "tshark_lua_packets_per_second": round(statistics.median(plugin_runs)),
        "tshark_alone_packets_per_second": round(statistics.median(plain_runs)),
        "rounds": options.rounds,
    }
    if options.json:
        print(json.dumps(result))
        return
    print(
        f"tshark + generated Lua dissector: {result['tshark_lua_packets_per_second']:,} packets/s"
        f" ({lines:,} packets, median of {options.rounds})"
    )
    alone = result["tshark_alone_packets_per_second"]
    print(f"tshark alone (up to UDP):         {alone:,} packets/s")


if __name__ == "__main__":
    main()
