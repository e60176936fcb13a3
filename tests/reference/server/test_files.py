"""The robot's files over HTTP (paper Fig. 5), and nothing else, whatever a request asks."""

from __future__ import annotations

import asyncio
import socket
import struct
import urllib.request
from pathlib import Path

import pytest
from support.processes import BOUND, running
from support.robots import CAMERA
from support.servers import run, serving


async def http(port: int, request: bytes) -> tuple[int, dict[str, str], bytes]:
    reader, writer = await asyncio.open_connection("127.0.0.1", port)
    writer.write(request)
    await writer.drain()
    head = await asyncio.wait_for(reader.readuntil(b"\r\n\r\n"), 5)
    status_line, *lines = head.decode("latin-1").split("\r\n")
    headers = {k.lower(): v.strip() for k, _, v in (line.partition(":") for line in lines if line)}
    length = int(headers.get("content-length", "0"))
    body = b"" if request.startswith(b"HEAD") else await reader.readexactly(length)
    writer.close()
    return int(status_line.split()[1]), headers, body


def get(path: str, method: str = "GET") -> bytes:
    return f"{method} {path} HTTP/1.1\r\nHost: robot\r\nConnection: close\r\n\r\n".encode()


@run
async def test_the_rcml_and_its_panel_are_served_as_they_are() -> None:
    async with serving(CAMERA) as server:
        assert server.http_port is not None
        for name in ("camera.rcml", "camera.rxid"):
            status, headers, body = await http(server.http_port, get("/" + name))
            assert status == 200
            assert headers["content-type"] == "application/xml"
            assert body == (CAMERA.parent / name).read_bytes()
        status, headers, _ = await http(server.http_port, get("/camera.rcml", "HEAD"))
        assert status == 200
        assert int(headers["content-length"]) == CAMERA.stat().st_size
        status, _, index = await http(server.http_port, get("/"))
        assert status == 200
        assert b'href="/camera.rcml"' in index
        assert b'href="/camera.rxid"' in index


@pytest.mark.parametrize(
    ("request_bytes", "status"),
    [
        (get("/../camera/camera.rcml"), 404),
        (get("/%2e%2e/rover/rover.rcml"), 404),
        (get("/etc/passwd"), 404),
        (get("/camera.rcml", "POST"), 405),
        (b"GET / HTTP/1.1\r\n\r\n", 400),  # HTTP/1.1 needs Host
        (b"\x16\x03\x01 not http\r\n\r\n", 400),
    ],
    ids=["dot-dot", "encoded dot-dot", "elsewhere", "POST", "no Host", "garbage"],
)
@run
async def test_nothing_else_is_served(request_bytes: bytes, status: int) -> None:
    async with serving(CAMERA) as server:
        assert server.http_port is not None
        answer, _, _ = await http(server.http_port, request_bytes)
        assert answer == status


def _reset(port: int, data: bytes) -> None:
    """Send `data`, then end the connection with a reset (RST): SO_LINGER on, for 0 s."""
    with socket.create_connection(("127.0.0.1", port), timeout=BOUND) as peer:
        peer.sendall(data)
        peer.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))


@pytest.mark.parametrize(
    "sent",
    [b"GET /camera.rcml HTTP/1.1\r\nHo", b"\x16\x03\x01 not http\r\n\r\n", b""],
    ids=["partial request", "bad request", "nothing"],
)
def test_a_peer_that_resets_the_connection_ends_only_its_own(tmp_path: Path, sent: bytes) -> None:
    """A reset as the server reads, or as it answers "bad request", is no traceback on the
    server's standard error, and the next client is served."""
    with running(
        tmp_path, "serve", "--port", "0", "--http-port", "0", "-vv", str(CAMERA)
    ) as server:
        url = str(server.ready["http"])
        port = int(url.rsplit(":", 1)[1].strip("/"))
        # The server sees the reset at one moment or another of its answer: a few tries meet
        # most of them.
        for _ in range(10):
            _reset(port, sent)
        with urllib.request.urlopen(url + "camera.rcml", timeout=BOUND) as answer:
            assert answer.read() == CAMERA.read_bytes()
        status, _, err = server.stop()
    assert status == 0, err
    for broken in ("Traceback", "Unhandled exception", "ConnectionResetError"):
        assert broken not in err
