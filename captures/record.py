#!/usr/bin/env python3
"""Record the captures of captures/ from the reference implementation, on loopback.

    sudo .venv/bin/python captures/record.py            # all four
    sudo .venv/bin/python captures/record.py rsp-cubo-impaired malformed
    sudo .venv/bin/python captures/record.py --out /tmp/again      # elsewhere

Each capture starts the reference processes it needs (`rcmlconf serve`, `rcmlconf robot`) as
subprocesses on their default ports, drives them with the reference client and simulacrum (and,
for the malformed one, with bytes written by hand on plain sockets), and records loopback with
dumpcap and a BPF filter of those ports. Where a capture goes through `rcmlconf.impair`'s
`ImpairProxy`, the legs on the far side of the proxy are left out, so that the file shows one end's
view of an impaired path (captures/README.md says which). Then the plugin of `rcmlconf wireshark
--model cubo.rmodel` reads the file with tshark, and what it shows is written beside it as
NAME.expected.json (`rcmlconf.wireshark.tshark.analyse`), with what the recorder knows that the
file cannot tell (the proxy's own counts of what it lost, duplicated and held back).

Needs root (or dumpcap's capabilities) to capture, tshark and dumpcap, and ports 7330 (TCP and
UDP), 7340 and 7341 (UDP) free. Timing makes each run's packets differ; the expected files are
always those of the pcap written with them.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import json
import os
import shutil
import signal
import socket
import struct
import subprocess
import sys
import tempfile
import time
from dataclasses import asdict
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from rcmlconf.impair import parse_impairment  # noqa: E402
from rcmlconf.impair.proxy import ImpairProxy  # noqa: E402
from rcmlconf.rctp.datastream.flow import (  # noqa: E402
    Direction,
    IntervalGet,
    IntervalSet,
    TimeoutGet,
    TimeoutSet,
)
from rcmlconf.rctp.fields import Transport  # noqa: E402
from rcmlconf.reference.client.adapter import Client  # noqa: E402
from rcmlconf.reference.client.session import ServerRequest  # noqa: E402
from rcmlconf.reference.rsp.simulacrum import Simulacrum  # noqa: E402
from rcmlconf.rsp.codec import Header, Hello, Packet, PacketType, RspCodec  # noqa: E402
from rcmlconf.rsp.codec.header import Encryption  # noqa: E402
from rcmlconf.validate.validator import load_robot, load_robot_model  # noqa: E402
from rcmlconf.wireshark.lua import generate_lua  # noqa: E402
from rcmlconf.wireshark.tshark import analyse, run_tshark  # noqa: E402

CAPTURES = ROOT / "captures"
ROVER = ROOT / "rcmlconf/reference/robots/rover/rover.rcml"
CUBO = ROOT / "rcmlconf/reference/robots/cubo/cubo.rmodel"
HOST = "127.0.0.1"
RCTP_PORT = 7330
RSP_PORT = 7340
#: Where the robot really listens when the proxy takes 7340.
HIDDEN_RSP_PORT = 7341
URL = f"rctp://{HOST}:{RCTP_PORT}/rover"
#: Every impairment's seed: the same datagrams in the same order meet the same fates.
SEED = 7330
RCTP_IMPAIRMENT = "loss=10%,reorder=5%,gap=30ms,duplicate=3%"
RSP_IMPAIRMENT = "loss=20%,reorder=5%,gap=30ms"


# -- processes ---------------------------------------------------------------------------------


class Capture:
    """dumpcap on loopback with a BPF filter, into a classic pcap file."""

    def __init__(self, bpf: str, path: Path) -> None:
        self.bpf = bpf
        self.path = path
        self.process: subprocess.Popen[bytes] | None = None

    def __enter__(self) -> Capture:
        dumpcap = shutil.which("dumpcap")
        if dumpcap is None:
            raise SystemExit("record.py: dumpcap is not installed (apt-get install tshark)")
        self.process = subprocess.Popen(
            [dumpcap, "-i", "lo", "-P", "-f", self.bpf, "-w", str(self.path)],
            stderr=subprocess.PIPE,
        )
        assert self.process.stderr is not None
        said = b""
        while b"Capturing on" not in said:
            line = self.process.stderr.readline()
            if not line:
                raise SystemExit(f"record.py: dumpcap did not start: {said.decode()}")
            said += line
        time.sleep(0.3)  # the filter is attached before it says so; the ring may lag
        return self

    def __exit__(self, *exc: object) -> None:
        time.sleep(0.5)  # the last packets reach the file
        assert self.process is not None
        self.process.send_signal(signal.SIGTERM)
        self.process.wait(timeout=10)


class Reference:
    """A reference process (`rcmlconf serve`, `rcmlconf robot`) started with a ready file."""

    def __init__(self, *arguments: str) -> None:
        self.arguments = arguments
        self.process: subprocess.Popen[bytes] | None = None
        self.log = ""

    def __enter__(self) -> Reference:
        self._directory = tempfile.TemporaryDirectory(prefix="rcmlconf-record-")
        ready = Path(self._directory.name) / "ready.json"
        self.process = subprocess.Popen(
            [sys.executable, "-m", "rcmlconf", *self.arguments, "--ready-file", str(ready)],
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            cwd=ROOT,
        )
        deadline = time.monotonic() + 20
        while not ready.exists():
            if self.process.poll() is not None or time.monotonic() > deadline:
                out = self.process.communicate()[0].decode(errors="replace")
                raise SystemExit(f"record.py: rcmlconf {self.arguments[0]} did not start: {out}")
            time.sleep(0.05)
        return self

    def stop(self) -> None:
        """Ctrl-C, as an operator stops it: BYE to every session, then exit."""
        if self.process is not None and self.process.poll() is None:
            self.process.send_signal(signal.SIGINT)
            try:
                self.log = self.process.communicate(timeout=10)[0].decode(errors="replace")
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()

    def __exit__(self, *exc: object) -> None:
        self.stop()
        self._directory.cleanup()


def serve(*faults: str) -> Reference:
    arguments = ["serve", str(ROVER), "--host", HOST, "--port", str(RCTP_PORT), "--no-http"]
    for fault in faults:
        arguments += ["--fault", fault]
    return Reference(*arguments)


def robot(port: int) -> Reference:
    return Reference("robot", str(CUBO), "--host", HOST, "--port", str(port))


# -- the captures ------------------------------------------------------------------------------


async def _drain(client: Client, seconds: float) -> list[object]:
    """The client's events for `seconds`: stream values, the server's requests, clock estimates."""
    got: list[object] = []
    deadline = client.loop.time() + seconds
    while (left := deadline - client.loop.time()) > 0:
        event = await client.next_event(timeout=left)
        if event is None and client.closed is not None:
            break
        if event is not None:
            got.append(event)
    return got


async def _flow_requests(client: Client, path: str) -> None:
    """Flow control on a playing stream (D-RCTP-22): get and set an interval and a timeout,
    and a request about a stream the session has not set up (NACK 2)."""
    endpoint = client.session.endpoint
    assert endpoint is not None
    stream = client.session.streams[path]
    builds = [
        (lambda rid: IntervalGet(rid, Direction.READ), stream),
        (lambda rid: IntervalSet(rid, Direction.READ, 40_000), stream),
        (lambda rid: TimeoutGet(rid, Direction.WRITE), stream),
        (lambda rid: TimeoutSet(rid, Direction.WRITE, 1_000_000), stream),
        (lambda rid: IntervalGet(rid, Direction.READ), 99),
    ]
    for build, stream_id in builds:
        endpoint.request(build, stream_id, client.loop.time())
        client._flush()
        await asyncio.sleep(0.2)


async def _full_session() -> dict[str, object]:
    model = load_robot(ROVER)
    notes: dict[str, object] = {}
    a = await Client.connect(URL, model)
    await a.read("/identity/info/name")
    await a.read("/identity/info/serial")
    await a.read("/sensors/events")
    await a.setup("/drive/settings")
    await a.go("/drive/settings")
    # Another operator changes the settings: the server pushes them to A (D-RCTP-27).
    b = await Client.connect(URL, model)
    await b.acquire("/drive")
    await b.write("/drive/settings", {"maxSpeed": 0.8, "mode": 1})
    await asyncio.sleep(0.1)
    await b.write("/drive/settings", {"maxSpeed": 0.6, "mode": 2})
    await asyncio.sleep(0.1)
    await b.close()
    pushed = [e for e in await _drain(a, 0.3) if isinstance(e, ServerRequest)]
    notes["server_writes_to_a"] = len(pushed)
    await a.acquire("/drive")
    await a.write("/drive/settings", {"maxSpeed": 0.5, "mode": 1})
    # A stream both ways, with heartbeats (the first at GO, the next 5 s later) and flow control.
    await a.setup("/drive/wheels", mode="both")
    a.write_values("/drive/wheels", {"left": 0.2, "right": 0.2})
    await a.go("/drive/wheels")
    await _drain(a, 1.0)
    await _flow_requests(a, "/drive/wheels")
    await _drain(a, 4.5)
    await a.pause("/drive/wheels")
    await _drain(a, 0.3)
    await a.go("/drive/wheels")
    await _drain(a, 0.3)
    await a.stop("/drive/wheels")
    await a.pause("/drive/settings")
    await a.stop("/drive/settings")
    # A writing stream fed nothing: the server ends it after its write timeout (D-RCTP-23).
    await a.setup("/drive/wheels", mode="write")
    await a.go("/drive/wheels")
    stops = [e for e in await _drain(a, 1.5) if isinstance(e, ServerRequest) and e.method == "STOP"]
    notes["server_stops"] = len(stops)
    await a.release("*")
    await a.close()
    # A session open when the server stops: its BYE (Reason: shutdown).
    c = await Client.connect(URL, model)
    notes["clients"] = 3
    return {"notes": notes, "waiting": c}


async def record_full_session(path: Path) -> dict[str, object]:
    with serve() as server, Capture(f"tcp port {RCTP_PORT} or udp port {RCTP_PORT}", path):
        result = await _full_session()
        c = result.pop("waiting")
        assert isinstance(c, Client)
        await asyncio.sleep(0.2)
        await asyncio.get_running_loop().run_in_executor(None, server.stop)
        events = await _drain(c, 0.5)
        result["notes"]["server_bye"] = sum(  # type: ignore[index]
            1 for e in events if isinstance(e, ServerRequest) and e.method == "BYE"
        )
        await c.close()
    return result


async def record_impaired_session(path: Path) -> dict[str, object]:
    """The data stream through `ImpairProxy`, as the robot sees it.

    The client's data socket is behind the proxy: SETUP's `client_port` is the proxy's, so the
    server sends there and takes the client's packets from there (R-RCTP-56), and the client
    sends to the proxy's socket towards it. The capture keeps the server's side: the client's
    packets after the impairment, the server's before it.
    """
    model = load_robot(ROVER)
    impairment = parse_impairment(RCTP_IMPAIRMENT)
    with serve(), Capture(f"tcp port {RCTP_PORT} or udp port {RCTP_PORT}", path):
        a = await Client.connect(URL, model)
        await a.acquire("/drive")
        client_port = await a._data_port()
        proxy = ImpairProxy((HOST, client_port), impairment, SEED, listen=(HOST, 0))
        await proxy.start()
        transport = Transport(client_port=proxy.address[1], mode="both")
        await a.request("SETUP", "/drive/wheels", [("Transport", str(transport))])
        # The flow of the server's packets, opened now, so that the client's first packets
        # already have the proxy's socket to go to.
        flow = proxy._open((HOST, RCTP_PORT))
        opening = flow.opening
        assert opening is not None
        await opening
        assert flow.transport is not None
        assert a.session.endpoint is not None
        a.session.endpoint.peer = (HOST, flow.transport.get_extra_info("sockname")[1])
        a.write_values("/drive/wheels", {"left": 0.3, "right": -0.3})
        await a.go("/drive/wheels")
        await _drain(a, 1.0)
        await _flow_requests(a, "/drive/wheels")
        await _drain(a, 5.0)
        await a.stop("/drive/wheels")
        await a.close()
        await proxy.close()
        counts = proxy.counts
    return {
        "impairment": str(impairment),
        "seed": SEED,
        "view": "the server's: client packets after the impairment, server packets before",
        "proxy": {
            "client_to_server": asdict(counts.backward),
            "server_to_client": asdict(counts.forward),
        },
    }


async def record_rsp(path: Path) -> dict[str, object]:
    """A CUBO run through `ImpairProxy`, as the local system sees it: the proxy listens on 7340,
    where the local system believes the robot is, and the robot on 7341 is left out."""
    model = load_robot_model(CUBO)
    impairment = parse_impairment(RSP_IMPAIRMENT)
    with robot(HIDDEN_RSP_PORT), Capture(f"udp port {RSP_PORT}", path):
        proxy = ImpairProxy((HOST, HIDDEN_RSP_PORT), impairment, SEED, listen=(HOST, RSP_PORT))
        await proxy.start()
        simulacrum = Simulacrum(model, (HOST, RSP_PORT))
        await simulacrum.open()
        simulacrum.set_active("base", True)
        simulacrum.set_active("arms", True)
        simulacrum.write("leftWheel", {"speed": 120})
        simulacrum.write("rightWheel", {"speed": 100})
        simulacrum.set_active("position", True)
        simulacrum.set_active("leftWheelMonitor", True)
        simulacrum.set_active("lowBattery", True)
        simulacrum.issue("irFire", {"code": 0x20DF})
        for step in range(8):  # motion keyframes: memory commands, resent until acknowledged
            angle = 100 * (step + 1)
            simulacrum.issue(
                "motion",
                {"duration": 200, "leftArm": angle, "rightArm": -angle, "headTilt": 0},
            )
            await asyncio.sleep(0.25)
        simulacrum.issue("irFire", {"code": 0x10EF})
        await asyncio.sleep(0.5)
        simulacrum.set_period(0.04)  # PERIOD, in the next three periods (D-RSP-13)
        await asyncio.sleep(1.0)
        await simulacrum.aclose()
        await asyncio.sleep(0.3)
        await proxy.close()
        counts = proxy.counts
    return {
        "impairment": str(impairment),
        "seed": SEED,
        "view": "the local system's: its packets before the impairment, the robot's after",
        "proxy": {
            "local_to_robot": asdict(counts.forward),
            "robot_to_local": asdict(counts.backward),
        },
    }


def _tcp_exchange(payload: bytes, wait: float = 0.5) -> bytes:
    """Send bytes on a new connection to the server, and read what comes back until it closes."""
    with socket.create_connection((HOST, RCTP_PORT), timeout=2) as conn:
        conn.sendall(payload)
        answer = b""
        deadline = time.monotonic() + wait
        with contextlib.suppress(OSError):
            while time.monotonic() < deadline:
                chunk = conn.recv(65536)
                if not chunk:
                    break
                answer += chunk
        return answer


def _udp(payload: bytes, port: int) -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.sendto(payload, (HOST, port))
    time.sleep(0.05)


def _rsp_session(codec: RspCodec) -> tuple[socket.socket, int]:
    """A session opened by hand: HELLO, and the session ID of the WELCOME."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.settimeout(2)
    hello = Header(1, codec.model.model_id, Encryption.NONE, PacketType.HELLO, 0, 0, 0, 0, 0)
    sock.sendto(codec.push_packet(Packet(hello, Hello(bytes(range(16)), 20))), (HOST, RSP_PORT))
    welcome = codec.pull_packet(sock.recv(65536))
    return sock, welcome.header.session_id


def _rsp_header(kind: int, sequence: int, session: int, body: bytes) -> bytes:
    return struct.pack(">BHBBHIHIHB", 1, 1, 0, kind, sequence, sequence * 20,
                       session >> 32, session & 0xFFFFFFFF, 0, 0) + body  # fmt: skip


def record_malformed(path: Path) -> dict[str, object]:
    sent: list[str] = []
    bpf = f"tcp port {RCTP_PORT} or udp port {RCTP_PORT} or udp port {RSP_PORT}"
    with Capture(bpf, path):
        # A server that ends its lines in a bare LF (the reference's own fault, for harnesses).
        with serve("bare-lf"):
            _tcp_exchange(b"CONNECT /rover RCTP/2.0\r\nCSeq: 1\r\nUser-Agent: record.py\r\n\r\n")
            sent.append("a server answering CONNECT with bare LF line ends (--fault bare-lf)")
        with serve():
            _tcp_exchange(b"HELLO WORLD\r\n\r\n")
            sent.append("a request line of two words")
            _tcp_exchange(b"CONNECT /rover RCTP/2.0\nCSeq: 1\n\n")
            sent.append("a request with bare LF line ends")
            _tcp_exchange(
                b"FETCH /rover RCTP/2.0\r\nCSeq: 1\r\n\r\n"
                b"CONNECT /rover RCTP/1.0\r\nCSeq: 2\r\n\r\n"
                b"CONNECT /rover RCTP/2.0\r\nCSeq: 3\r\n\r\n"
                b"GARBAGE\x01 /rover RCTP/2.0\r\n\r\n"
            )
            sent.append("pipelined: an unknown method, another version, a CONNECT, a garbage line")
            _tcp_exchange(b"CONNECT /" + b"x" * 5000 + b" RCTP/2.0\r\nCSeq: 1\r\n\r\n")
            sent.append("a start line of more than 4,096 bytes")
            _tcp_exchange(
                b"WRITE /drive/settings RCTP/2.0\r\nCSeq: 1\r\nContent-Length: ten\r\n\r\n"
            )
            sent.append("a Content-Length that is no number")
            header = struct.pack(">BBHIQ", 2, 1, 100, 0xDEADBEEF, 0xEBE6BF4080000000)
            _udp(struct.pack(">BBHIQ", 3, 1, 100, 0xDEADBEEF, 0) + b"\x01\x01\x00\x00", RCTP_PORT)
            sent.append("a data-stream packet of version 3")
            _udp(header + struct.pack(">BBH", 1, 1, 40) + b"\x00" * 8, RCTP_PORT)
            sent.append("a data-stream packet whose body length runs past the end")
            _udp(header + struct.pack(">BBH", 2, 0, 6) + b"\x00\x01\x00\x07\x00\x00", RCTP_PORT)
            sent.append("a data-stream packet with a heartbeat request of 2 bytes of fields")
        with robot(RSP_PORT):
            codec = RspCodec(load_robot_model(CUBO))
            _udp(bytes.fromhex("0100010004000100000000"), RSP_PORT)
            sent.append("an RSP header cut short (11 bytes)")
            hello = _rsp_header(1, 0, 0, bytes(range(16)) + struct.pack(">H", 0))
            _udp(hello, RSP_PORT)
            sent.append("a HELLO asking for a period of 0 ms")
            sock, session = _rsp_session(codec)
            with sock:
                too_fast = _rsp_header(4, 1, session, bytes.fromhex("60000000") + b"\x02\x58" * 2)
                sock.sendto(too_fast, (HOST, RSP_PORT))
                sent.append("a DOWNLINK whose wheel speed 600 is outside -500 to 500")
                past = _rsp_header(4, 2, session, bytes.fromhex("00000040"))
                sock.sendto(past, (HOST, RSP_PORT))
                sent.append("a DOWNLINK with a Device Map bit past CUBO's 25 devices")
                truncated = _rsp_header(4, 3, session, bytes.fromhex("6000000000"))
                sock.sendto(truncated, (HOST, RSP_PORT))
                sent.append("a DOWNLINK whose payloads are cut short")
                bye = _rsp_header(7, 4, session, b"\x00")
                sock.sendto(bye, (HOST, RSP_PORT))
                time.sleep(0.2)
    return {"sent": sent}


CAPTURES_RECORDED = {
    "rctp-session": record_full_session,
    "rctp-impaired": record_impaired_session,
    "rsp-cubo-impaired": record_rsp,
    "malformed": record_malformed,
}


def plugin(directory: Path) -> Path:
    """The plugin the expected files are written with: `rcmlconf wireshark --model cubo.rmodel`."""
    path = directory / "rcml-cubo.lua"
    path.write_text(generate_lua(load_robot_model(CUBO)), encoding="utf-8")
    return path


def expected(pcap: Path, lua: Path, recorded: dict[str, object]) -> dict[str, object]:
    run = run_tshark(pcap, lua)
    if run.problems:
        raise SystemExit(f"record.py: tshark said: {run.problems}")
    return {
        "capture": pcap.name,
        "plugin": "rcmlconf wireshark --model rcmlconf/reference/robots/cubo/cubo.rmodel",
        "bytes": pcap.stat().st_size,
        "tshark": analyse(run),
        "recorded": recorded,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("names", nargs="*", choices=[*CAPTURES_RECORDED, []], metavar="NAME")
    parser.add_argument(
        "--out", type=Path, default=CAPTURES, help="where to write them (default: captures/)"
    )
    options = parser.parse_args()
    names = options.names or list(CAPTURES_RECORDED)
    out: Path = options.out
    out.mkdir(parents=True, exist_ok=True)
    if os.geteuid() != 0:
        print("record.py: capturing on lo needs root (or dumpcap's capabilities)", file=sys.stderr)
    with tempfile.TemporaryDirectory(prefix="rcmlconf-record-") as work:
        lua = plugin(Path(work))
        for name in names:
            pcap = out / f"{name}.pcap"
            raw = Path(work) / f"{name}.raw.pcap"
            record = CAPTURES_RECORDED[name]
            if asyncio.iscoroutinefunction(record):
                recorded = asyncio.run(record(raw))
            else:
                recorded = record(raw)
            shutil.copyfile(raw, pcap)
            os.chmod(pcap, 0o644)
            document = expected(pcap, lua, recorded)
            target = out / f"{name}.expected.json"
            target.write_text(json.dumps(document, indent=1) + "\n", encoding="utf-8")
            frames = document["tshark"]["frames"]  # type: ignore[index]
            print(f"{pcap}: {document['bytes']:,} bytes, {frames} frames")


if __name__ == "__main__":
    main()
