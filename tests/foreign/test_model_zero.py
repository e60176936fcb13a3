"""No model has model ID 0: a packet with it is malformed and dropped without an answer
(D-RSP-10, R-RSP-18). A HELLO with it is not refused: it names no model to echo.

Both RSP implementations of tests/foreign/ are run as users run them, over real UDP sockets on
127.0.0.1, and told apart only by what they send.
"""

from __future__ import annotations

import json
import os
import signal
import socket
import struct
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

FOREIGN = Path(__file__).resolve().parent
HEADER = struct.Struct(">BHBBHI6sHB")  # D-RSP-10
HELLO, WELCOME, REFUSED, DOWNLINK = 1, 2, 3, 4  # D-RSP-11
QUIET = 1.0  # seconds in which a dropped packet must get no answer
BOUND = 10.0  # seconds for anything that must come


def model_id(folder: str) -> int:
    """The modelId of an implementation's own robot.rmodel."""
    return int(ET.parse(FOREIGN / folder / "robot.rmodel").getroot().attrib["modelId"])


def header(model: int, kind: int, seq: int = 0, session: int = 0, last: int = 0) -> bytes:
    """A plaintext header: version 1, encryption 0, timestamp 0."""
    return HEADER.pack(1, model, 0, kind, seq, 0, session.to_bytes(6, "big"), last, 0)


def hello(model: int, seq: int, nonce: bytes) -> bytes:
    """A well-formed plaintext HELLO asking for T = 20 ms (D-RSP-11, D-RSP-12)."""
    return header(model, HELLO, seq) + nonce + struct.pack(">H", 20)


def receive(sock: socket.socket, seconds: float) -> bytes | None:
    """The next datagram within seconds, or None."""
    sock.settimeout(seconds)
    try:
        return sock.recv(65536)
    except TimeoutError:
        return None


def stop(process: subprocess.Popen[bytes]) -> None:
    if process.poll() is None:
        process.send_signal(signal.SIGTERM)
        try:
            process.wait(BOUND)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait(BOUND)


@contextmanager
def robot(tmp_path: Path) -> Iterator[tuple[socket.socket, tuple[str, int]]]:
    """rsp_robot on a free port, and a UDP socket to talk to it from."""
    ready = tmp_path / "ready.json"
    main = FOREIGN / "rsp_robot" / "main.py"
    process = subprocess.Popen(
        [sys.executable, str(main), "--port", "0", "--ready-file", str(ready)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        deadline = time.monotonic() + BOUND
        while not ready.exists():
            assert process.poll() is None, "the robot exited"
            assert time.monotonic() < deadline, "the robot never said it listens"
            time.sleep(0.02)
        port = json.loads(ready.read_text())["port"]
        sock.bind(("127.0.0.1", 0))
        yield sock, ("127.0.0.1", port)
    finally:
        sock.close()
        stop(process)


def test_the_robot_drops_a_hello_of_model_zero(tmp_path: Path) -> None:
    ours = model_id("rsp_robot")
    nonce = os.urandom(16)
    with robot(tmp_path) as (sock, address):
        sock.sendto(hello(0, 0, nonce), address)
        answer = receive(sock, QUIET)
        assert answer is None, f"answered a HELLO of model 0: {answer.hex()}"

        # another model that is not 0 is still refused, its model ID echoed (R-RSP-21)
        other = ours % 65535 + 1
        sock.sendto(hello(other, 1, nonce), address)
        answer = receive(sock, BOUND)
        assert answer is not None, "no REFUSED to a HELLO of another model"
        fields = HEADER.unpack_from(answer)
        assert (fields[1], fields[3], answer[20:]) == (other, REFUSED, b"\x01")

        # the robot's own model is welcomed
        sock.sendto(hello(ours, 2, nonce), address)
        answer = receive(sock, BOUND)
        assert answer is not None, "no WELCOME to a HELLO of the robot's model"
        fields = HEADER.unpack_from(answer)
        assert (fields[1], fields[3]) == (ours, WELCOME)
        assert answer[20:36] == nonce


def test_the_local_system_drops_a_welcome_of_model_zero() -> None:
    """rsp_local, with a socket here for its robot: a WELCOME of model 0 is not taken (the
    local system sends its HELLO again), and the same WELCOME of the model is (a DOWNLINK
    follows)."""
    ours = model_id("rsp_local")
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    port = sock.getsockname()[1]
    folder = FOREIGN / "rsp_local"
    process = subprocess.Popen(
        [
            sys.executable,
            str(folder / "main.py"),
            "--robot",
            f"127.0.0.1:{port}",
            "--model",
            str(folder / "robot.rmodel"),
        ],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:

        def next_packet() -> tuple[bytes, tuple[str, int]]:
            sock.settimeout(BOUND)
            data, peer = sock.recvfrom(65536)
            return data, peer

        def welcome(model: int, first: bytes) -> bytes:
            seq = HEADER.unpack_from(first)[4]
            nonce = first[20:36]
            body = nonce + os.urandom(16) + struct.pack(">H", 20)
            return header(model, WELCOME, 0, 0x1234_5678_9ABC, seq) + body

        first, peer = next_packet()
        assert HEADER.unpack_from(first)[3] == HELLO
        sock.sendto(welcome(0, first), peer)
        again, _ = next_packet()
        assert HEADER.unpack_from(again)[3] == HELLO, "a WELCOME of model 0 was taken"
        sock.sendto(welcome(ours, again), peer)
        deadline = time.monotonic() + BOUND
        while True:  # a repeated HELLO may already be on its way
            data, _ = next_packet()
            if HEADER.unpack_from(data)[3] != HELLO:
                break
            assert time.monotonic() < deadline, "the WELCOME of the model was not taken"
        fields = HEADER.unpack_from(data)
        assert (fields[1], fields[3]) == (ours, DOWNLINK)
        assert int.from_bytes(fields[6], "big") == 0x1234_5678_9ABC
    finally:
        sock.close()
        stop(process)
