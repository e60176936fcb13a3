"""The robot's files over HTTP (paper Fig. 5), and nothing else, whatever a request asks."""

from __future__ import annotations

import asyncio

import pytest
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
