"""An independent RSP robot (specs/rsp.md), written from specs/ alone.

    python main.py [--model robot.rmodel] [--port 7340] [--ready-file F] [--psk-file KEY]
                   [--fault NAME ...] [--list-faults] [--bug NAME ...] [--list-bugs] [-v]

It serves one session at a time on UDP until SIGINT or SIGTERM, then ends the session with BYE
(reason 2, shutdown) and exits 0.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import selectors
import signal
import socket
import sys
import tempfile
import time
import traceback
from pathlib import Path

import bugs
from rmodel import ModelError, load_model
from robot import FAULTS, Out, Robot, log
from wire import read_psk

HERE = Path(__file__).resolve().parent
DEFAULT_PORT = 7340  # D-RSP-9
READS_A_WAKEUP = 64


def parse_args(argv: list[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description="An independent RSP robot of its own model.")
    parser.add_argument("--model", type=Path, default=HERE / "robot.rmodel")
    parser.add_argument("--host", default="127.0.0.1", help="address to listen on")
    parser.add_argument("--port", type=int, default=DEFAULT_PORT, help="UDP port, 0 for any")
    parser.add_argument("--ready-file", type=Path, help='write {"port": P} here once listening')
    parser.add_argument(
        "--psk-file",
        type=Path,
        help="pre-shared key (64 hex digits or 32 bytes): offer AES-256-GCM and ChaCha20-Poly1305",
    )
    parser.add_argument("--fault", action="append", default=[], metavar="NAME")
    parser.add_argument("--list-faults", action="store_true")
    parser.add_argument(
        "--bug",
        action="append",
        default=[],
        metavar="NAME",
        help="plant a robustness bug, for the fuzzer's tests (see --list-bugs)",
    )
    parser.add_argument("--list-bugs", action="store_true", help="print the planted bugs")
    parser.add_argument("-v", "--verbose", action="store_true")
    args = parser.parse_args(argv)
    if not 0 <= args.port <= 65535:
        parser.error("--port must be 0 to 65535")
    unknown = [name for name in args.fault if name not in FAULTS]
    if unknown:
        parser.error(f"unknown fault {unknown[0]} (see --list-faults)")
    unknown = [name for name in args.bug if name not in bugs.BUGS]
    if unknown:
        parser.error(f"unknown bug {unknown[0]} (see --list-bugs)")
    return args


def write_ready(path: Path, port: int) -> None:
    """Write {"port": P} atomically: a temporary file beside it, then rename."""
    fd, temporary = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.")
    with os.fdopen(fd, "w") as stream:
        json.dump({"port": port}, stream)
    os.replace(temporary, path)


def send(sock: socket.socket, out: Out) -> None:
    for data, address in out:
        try:
            sock.sendto(data, address)
        except OSError as exc:  # an ICMP error from an earlier datagram, a full buffer
            log(f"send to {address[0]}:{address[1]} failed: {exc}")


def serve(args: argparse.Namespace) -> int:
    try:
        # onloss-default-zero: the reader's default for a missing onLoss is wrong
        on_loss_default = "zero" if "onloss-default-zero" in args.fault else "hold"
        model = load_model(args.model.read_bytes(), on_loss_default)
        psk = read_psk(args.psk_file.read_bytes()) if args.psk_file else None
    except (OSError, ModelError, ValueError) as exc:
        log(f"rsp_robot: {exc}")
        return 1
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        sock.bind((args.host, args.port))
    except OSError as exc:
        log(f"rsp_robot: cannot listen on {args.host}:{args.port}: {exc}")
        return 2
    sock.setblocking(False)
    port = sock.getsockname()[1]
    wake_r, wake_w = socket.socketpair()
    wake_r.setblocking(False)
    wake_w.setblocking(False)
    signal.set_wakeup_fd(wake_w.fileno())
    stopping: list[int] = []
    for number in (signal.SIGINT, signal.SIGTERM):
        signal.signal(number, lambda signum, _frame: stopping.append(signum))
    selector = selectors.DefaultSelector()
    selector.register(sock, selectors.EVENT_READ)
    selector.register(wake_r, selectors.EVENT_READ)
    robot = Robot(model, psk, set(args.fault), args.verbose, time.monotonic())
    if args.ready_file:
        write_ready(args.ready_file, port)
    log(f"rsp_robot: {model.name} (model {model.model_id}) on UDP {args.host}:{port}")
    try:
        while not stopping:
            deadline = robot.deadline()
            timeout = None if deadline is None else max(0.0, deadline - time.monotonic())
            for key, _ in selector.select(timeout):
                if key.fileobj is wake_r:
                    with contextlib.suppress(BlockingIOError):
                        wake_r.recv(64)
                    continue
                for _ in range(READS_A_WAKEUP):
                    try:
                        data, address = sock.recvfrom(65536)
                    except (BlockingIOError, InterruptedError):
                        break
                    except OSError:  # ICMP port unreachable from an earlier send
                        continue
                    try:
                        out = robot.on_datagram(data, address[:2], time.monotonic())
                    except Exception:  # a bug must not stop the robot: log it, drop the datagram
                        log(traceback.format_exc())
                        out = []
                    send(sock, out)
            send(sock, robot.on_timer(time.monotonic()))
        send(sock, robot.shutdown(time.monotonic()))
    finally:
        selector.close()
        sock.close()
        wake_r.close()
        wake_w.close()
        if args.ready_file:
            args.ready_file.unlink(missing_ok=True)
    return 0


def main(argv: list[str]) -> int:
    args = parse_args(argv)
    if args.list_faults:
        for name, (requirement, description) in FAULTS.items():
            print(f"{name}\t{requirement}\t{description}")
        return 0
    if args.list_bugs:
        print(bugs.listing(), end="")
        return 0
    bugs.active = set(args.bug)
    return serve(args)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
