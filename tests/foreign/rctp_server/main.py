"""An independent RCTP/2.0 server of one robot, from specs/rctp-2.0.md and specs/rcml-2.0.md.

python main.py [--port P] [--http-port H] [--ready-file F] [--rcml FILE] [--fault NAME]...
    [--bug NAME]...
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import html
import json
import os
import signal
import socket
import sys
from pathlib import Path
from urllib.parse import quote, unquote, urlsplit

import bugs
from rcml import RcmlError, Robot, check_streams, parse
from server import MAX_CONNECTIONS, Connection, Server, _Udp

FAULTS = {
    "server-cseq-from-zero": (
        "R-RCTP-4",
        "the server numbers its own WRITE/STOP/BYE requests from 0",
    ),
    "acquire-ignores-ancestor": (
        "R-RCTP-33",
        "ACQUIRE below a path another session holds is granted",
    ),
    "keep-privilege-on-close": ("R-RCTP-36", "a closed control connection keeps its privileges"),
    "seq-accepts-duplicate": (
        "R-RCTP-43",
        "a data packet repeating the highest sequence number is applied",
    ),
    "event-write-partial": (
        "R-RCTP-29",
        "an event WRITE with a bad value applies the values before it",
    ),
    "bool-nonzero-true": (
        "R-RCML-30",
        "a bool byte other than 0x00/0x01 is read as true, not refused",
    ),
    "int16-little-endian": ("R-RCML-30", "int16 and uint16 values are sent little-endian"),
    "range-unchecked-normal": ("R-RCTP-28", "a normal-access WRITE outside min/max is applied"),
    "echo-own-write": (
        "R-RCTP-54",
        "a session's own event WRITE comes back to it as a data-change WRITE",
    ),
    "no-write-timeout": (
        "R-RCTP-45",
        "a writing stream whose client falls silent is never stopped",
    ),
    "state-after-node": (
        "R-RCTP-20",
        "GO/PAUSE/STOP/SETUP check the node (404/405) before the state (455)",
    ),
    "flow-no-dedupe": (
        "R-RCTP-46",
        "a repeated FLOW request id is answered anew, not with the answer given",
    ),
    "accept-short-interval": (
        "R-RCTP-47",
        "a set-interval shorter than the RCML's readInterval is accepted",
    ),
    "unknown-method-close": (
        "R-RCTP-9",
        "an unknown method is answered 400 and the connection closed",
    ),
    "one-message-per-read": (
        "R-RCTP-13",
        "pipelined messages after the first of one read are dropped",
    ),
    "no-source-check": (
        "R-RCTP-42",
        "data packets from another address or port are accepted if the tag fits",
    ),
    "unbounded-server-requests": (
        "R-RCTP-55",
        "more than four server WRITE/STOP requests may be unanswered",
    ),
    "release-under-write-stream": (
        "R-RCTP-35",
        "RELEASE is granted while a writing stream below is set up",
    ),
    "send-while-paused": ("R-RCTP-44", "a paused stream keeps sending its DATA payloads"),
    "no-session-timeout": ("R-RCTP-21", "a session whose client falls silent never times out"),
    "nodes-order-unchecked": (
        "R-RCTP-30",
        "a Nodes field out of canonical order or naming a node twice is accepted",
    ),
    "string-size-unchecked": (
        "R-RCML-30",
        "a string or bytes value longer than its size is accepted",
    ),
    "seq-start-zero": ("R-RCTP-41", "the data-stream sequence numbers start at 0, not at random"),
    "heartbeat-t2-echo": ("R-RCTP-48", "the heartbeat ACK carries T1 again where T2 belongs"),
    "no-allow-field": ("R-RCTP-26", "405 responses carry no Allow field"),
    "setup-missing-client-port-ok": (
        "R-RCTP-57",
        "SETUP with a Transport lacking client_port is answered 200",
    ),
    "stop-init-at-sending": (
        "R-RCTP-66",
        "a server STOP puts its stream in init when sent, whatever the client answers",
    ),
    "session-id-any-case": (
        "R-RCTP-19",
        "a Session naming this session's ID in other letter case is taken as this session's",
    ),
    "acquire-above-keeps-below": (
        "R-RCTP-35",
        "ACQUIRE above held paths does not take them in: RELEASE of one of them is granted",
    ),
    "set-interval-write-acked": (
        "R-RCTP-46",
        "a set-interval of the write direction (the client's value) is ACKed, not NACK 4",
    ),
    "timeout-min-one-interval": (
        "R-RCTP-47",
        "a set-timeout is refused only below one write interval, not below twice it",
    ),
    "unknown-payload-drops-packet": (
        "R-RCTP-51",
        "a packet holding a payload of an unknown type is dropped whole",
    ),
    "start-line-limit-counts-crlf": (
        "R-RCTP-16",
        "the 4,096-byte start-line limit counts the CRLF: 4,095 and 4,096 bytes get 414",
    ),
    "client-port-first-setup-only": (
        "R-RCTP-56",
        "a repeated SETUP's new client_port is answered but DATA keeps going to the first",
    ),
    "head-length-zero": (
        "R-RCTP-64",
        "HTTP HEAD answers carry Content-Length: 0, not the GET's length",
    ),
}


def _args(argv: list[str] | None) -> argparse.Namespace:
    here = Path(__file__).resolve().parent
    ap = argparse.ArgumentParser(description="An RCTP/2.0 server of the robot its RCML describes.")
    ap.add_argument("--port", type=int, help="RCTP TCP port and data-stream UDP port (0: any free)")
    ap.add_argument(
        "--http-port", type=int, help="HTTP port of the robot's files (default: RCTP's + 1)"
    )
    ap.add_argument("--host", default="127.0.0.1", help="address to listen on (default 127.0.0.1)")
    ap.add_argument("--rcml", type=Path, default=here / "robot.rcml", help="the robot's RCML file")
    ap.add_argument(
        "--ready-file", type=Path, help="write {port, http_port, site} here once listening"
    )
    ap.add_argument(
        "--fault", action="append", default=[], metavar="NAME", help="misbehave (see --list-faults)"
    )
    ap.add_argument(
        "--session-timeout", type=int, default=60, help="session timeout in seconds (default 60)"
    )
    ap.add_argument("--list-faults", action="store_true", help="print the faults and exit")
    ap.add_argument(
        "--bug",
        action="append",
        default=[],
        metavar="NAME",
        help="plant a robustness bug, for the fuzzer's tests (see --list-bugs)",
    )
    ap.add_argument("--list-bugs", action="store_true", help="print the planted bugs and exit")
    ap.add_argument(
        "-v", "--verbose", action="store_true", help="a line for every request on stderr"
    )
    args = ap.parse_args(argv)
    unknown = [f for f in args.fault if f not in FAULTS]
    if unknown:
        ap.error(f"unknown fault(s) {', '.join(unknown)}; see --list-faults")
    unknown = [b for b in args.bug if b not in bugs.BUGS]
    if unknown:
        ap.error(f"unknown bug(s) {', '.join(unknown)}; see --list-bugs")
    if not 1 <= args.session_timeout <= 99999:
        ap.error("--session-timeout must be 1 to 99999 (five digits, D-RCTP-11)")
    for name in ("port", "http_port"):
        value = getattr(args, name)
        if value is not None and not 0 <= value <= 65535:
            ap.error(f"--{name.replace('_', '-')} must be 0 to 65535")
    return args


def _bind(
    host: str, port: int, http_port: int | None
) -> tuple[socket.socket, socket.socket, socket.socket]:
    """TCP and UDP on one port number (D-RCTP-2), HTTP on the next unless told (D-RCTP-29)."""
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    for _ in range(50):
        made: list[socket.socket] = []
        try:
            tcp = socket.socket(family, socket.SOCK_STREAM)
            made.append(tcp)
            tcp.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            tcp.bind((host, port))
            actual = tcp.getsockname()[1]
            udp = socket.socket(family, socket.SOCK_DGRAM)
            made.append(udp)
            udp.bind((host, actual))
            web = socket.socket(family, socket.SOCK_STREAM)
            made.append(web)
            web.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            web.bind((host, actual + 1 if http_port is None else http_port))
            return tcp, udp, web
        except OSError:
            for s in made:
                s.close()
            if port != 0:
                raise
    raise OSError("no free pair of ports found")


class Files:
    """D-RCTP-29: the RCML file, the RXID files its UserInterface links name, and an index."""

    def __init__(self, rcml_path: Path, robot: Robot, faults: set[str] | None = None) -> None:
        self.faults = faults or set()
        self.files: dict[str, tuple[bytes, str]] = {
            "/" + quote(rcml_path.name): (rcml_path.read_bytes(), "application/xml")
        }
        for kind, href in robot.links:
            parts = urlsplit(href)
            if kind != "UserInterface" or parts.scheme or parts.netloc or href.startswith("/"):
                continue
            local = (rcml_path.parent / unquote(parts.path)).resolve()
            if local.parent == rcml_path.parent.resolve() and local.is_file():
                self.files["/" + quote(local.name)] = (local.read_bytes(), "application/xml")
        links = "".join(
            f'<li><a href="{html.escape(p[1:])}">{html.escape(unquote(p[1:]))}</a></li>'
            for p in self.files
        )
        title = html.escape(robot.title or "robot")
        page = (
            f"<!DOCTYPE html><html><head><title>{title}</title></head>"
            f"<body><ul>{links}</ul></body></html>"
        )
        self.files["/"] = (page.encode("utf-8"), "text/html; charset=utf-8")

    async def serve(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        try:
            head = await asyncio.wait_for(reader.readuntil(b"\r\n\r\n"), 10)
            parts = head.split(b"\r\n", 1)[0].decode("latin-1").split(" ")
            if len(parts) != 3 or not parts[2].startswith("HTTP/1."):
                status, body, ctype = "400 Bad Request", b"bad request\n", "text/plain"
            elif parts[0] not in ("GET", "HEAD"):
                status, body, ctype = "405 Method Not Allowed", b"GET or HEAD\n", "text/plain"
            elif urlsplit(parts[1]).path in self.files:
                body, ctype = self.files[urlsplit(parts[1]).path]
                status = "200 OK"
            else:
                status, body, ctype = "404 Not Found", b"not found\n", "text/plain"
            allow = "Allow: GET, HEAD\r\n" if status.startswith("405") else ""
            length = len(body)
            if parts[0] == "HEAD" and "head-length-zero" in self.faults:
                length = 0  # the fault: a HEAD answer counts the body it leaves out
            writer.write(
                f"HTTP/1.1 {status}\r\nContent-Type: {ctype}\r\nContent-Length: {length}\r\n"
                f"{allow}Connection: close\r\n\r\n".encode("latin-1")
            )
            if parts[0] != "HEAD":
                writer.write(body)
            await writer.drain()
        except (
            TimeoutError,
            asyncio.IncompleteReadError,
            asyncio.LimitOverrunError,
            ConnectionError,
            ValueError,
        ):
            pass
        finally:
            writer.close()


async def _serve(args: argparse.Namespace, robot: Robot) -> int:
    loop = asyncio.get_running_loop()
    server = Server(robot, set(args.fault), args.verbose, args.session_timeout)
    port = args.port
    if port is None:
        port = urlsplit(robot.site).port or 7330
    try:
        tcp, udp, web = _bind(args.host, port, args.http_port)
    except OSError as exc:
        print(f"cannot listen: {exc}", file=sys.stderr)
        return 2
    udp_transport, _ = await loop.create_datagram_endpoint(lambda: _Udp(server), sock=udp)
    server.udp, server.udp_port = udp_transport, udp.getsockname()[1]

    async def control(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        if len(server.connections) >= MAX_CONNECTIONS:
            writer.close()
            return
        conn = Connection(server, reader, writer)
        server.connections.add(conn)
        await conn.run()

    rctp = await asyncio.start_server(control, sock=tcp, limit=65536)
    files = Files(args.rcml, robot, set(args.fault))
    http = await asyncio.start_server(files.serve, sock=web, limit=16384)
    ticker = asyncio.create_task(server.ticker())
    stop = asyncio.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        loop.add_signal_handler(sig, stop.set)
    ports = {
        "port": tcp.getsockname()[1],
        "http_port": web.getsockname()[1],
        "site": robot.site_path,
    }
    if args.ready_file:
        tmp = args.ready_file.with_name(args.ready_file.name + ".tmp")
        tmp.write_text(json.dumps(ports))
        os.replace(tmp, args.ready_file)
    url = f"rctp://{args.host}:{ports['port']}{robot.site_path}"
    print(f"RCTP {url} (UDP {server.udp_port}), HTTP {ports['http_port']}", flush=True)
    await stop.wait()
    rctp.close()
    http.close()
    for conn in list(server.connections):
        if conn.session is not None and conn.session.state == "open":
            conn.server_bye("shutdown")
        elif conn.session is None:
            conn.close()
    deadline = loop.time() + 5.5
    while server.connections and loop.time() < deadline:
        await asyncio.sleep(0.05)
    for conn in list(server.connections):
        conn.close()
    ticker.cancel()
    with contextlib.suppress(asyncio.CancelledError):
        await ticker
    udp_transport.close()
    return 0


def main(argv: list[str] | None = None) -> int:
    args = _args(argv)
    if args.list_faults:
        for name, (rule, text) in FAULTS.items():
            print(f"{name}\t{rule}\t{text}")
        return 0
    if args.list_bugs:
        print(bugs.listing(), end="")
        return 0
    bugs.active = set(args.bug)
    try:
        robot = parse(args.rcml.read_bytes())
        check_streams(robot)
    except (OSError, RcmlError) as exc:
        print(f"{args.rcml}: {exc}", file=sys.stderr)
        return 2
    return asyncio.run(_serve(args, robot))


if __name__ == "__main__":
    sys.exit(main())
