"""Stream-type access on loopback (§6): packets, flow control, heartbeats, the receive timeout."""

from __future__ import annotations

import asyncio
import socket
from functools import partial

from support.robots import CAMERA, ROVER, robot
from support.servers import run, serving

from rcmlconf.rctp.datastream.flow import Direction, IntervalSet
from rcmlconf.rctp.datastream.packets import pull_packet
from rcmlconf.reference.client.adapter import Client
from rcmlconf.reference.client.session import ServerRequest, StreamValues
from rcmlconf.reference.server.adapter import ReferenceServer

CONTROL = "/stream/control"
WHEELS = "/drive/wheels"


async def values(client: Client, path: str, count: int) -> list[StreamValues]:
    found: list[StreamValues] = []
    while len(found) < count:
        event = await client.next_event(timeout=2.0)
        assert event is not None, f"{len(found)} of {count} packets came"
        if isinstance(event, StreamValues) and event.path == path:
            found.append(event)
    return found


async def next_request(client: Client) -> ServerRequest:
    """The next server request, past the stream's values and clock estimates."""
    while True:
        event = await client.next_event(timeout=3.0)
        assert event is not None, "no server request came"
        if isinstance(event, ServerRequest):
            return event


def server_session_streams(server: ReferenceServer) -> dict[int, object]:
    (control,) = server.controls.values()
    assert control.session is not None
    assert control.session.endpoint is not None
    return control.session.endpoint.streams  # type: ignore[return-value]


@run
async def test_a_read_stream_carries_the_camera_moving_to_what_is_written() -> None:
    async with serving(CAMERA) as server:
        client = await Client.connect(server.url, robot(CAMERA))
        await client.acquire("/stream")
        await client.setup(CONTROL, "both")
        client.write_values(CONTROL, {"pan": 90, "tilt": 0, "zoom": 0, "focus": 0})
        await client.go(CONTROL)
        pans = [event.values["pan"] for event in await values(client, CONTROL, 30)]
        assert pans == sorted(pans)  # 60 deg/s toward 90: never back
        assert pans[-1] > pans[0]
        counts = client.session.endpoint.sequences.counts  # type: ignore[union-attr]
        assert counts.received >= 30
        await client.close()


@run
async def test_flow_control_changes_the_servers_interval() -> None:
    async with serving(CAMERA) as server:
        client = await Client.connect(server.url, robot(CAMERA))
        await client.setup(CONTROL, "read")
        await client.go(CONTROL)
        endpoint = client.session.endpoint
        assert endpoint is not None
        endpoint.request(partial(IntervalSet, direction=Direction.READ, interval=100_000), 1, 0.0)
        client._flush()
        for _ in range(200):
            if endpoint.streams[1].intervals[Direction.READ] == 100_000:
                break
            await asyncio.sleep(0.01)
        (stream,) = server_session_streams(server).values()
        assert stream.intervals[Direction.READ] == 100_000  # type: ignore[attr-defined]
        assert endpoint.streams[1].intervals[Direction.READ] == 100_000  # both ends agree
        await client.close()


@run
async def test_heartbeats_give_the_client_the_robots_clock() -> None:
    async with serving(CAMERA) as server:
        client = await Client.connect(server.url, robot(CAMERA))
        await client.setup(CONTROL, "read")
        await client.go(CONTROL)
        for _ in range(200):
            if client.clock is not None:
                break
            await asyncio.sleep(0.01)
        assert client.clock is not None
        # One host, one clock: the offset is within the uncertainty (R-RCTP-50).
        assert abs(client.clock.offset) <= client.clock.uncertainty + 0.01
        assert client.clock.uncertainty >= 1e-4  # never better than timePrecision
        await client.close()


@run
async def test_a_write_stream_without_data_is_stopped_by_the_server() -> None:
    async with serving(ROVER) as server:
        client = await Client.connect(server.url, robot(ROVER))
        await client.acquire("/drive")
        await client.setup(WHEELS, "write")
        await client.go(WHEELS)  # and nothing is ever written: the 0.5 s timeout passes
        stop = await next_request(client)
        assert stop == ServerRequest("STOP", WHEELS, 200, reason="timeout")  # R-RCTP-45
        assert WHEELS not in client.session.streams
        await client.setup(WHEELS, "write")  # it may be set up again (D-RCTP-23)
        await client.close()


@run
async def test_packets_go_to_the_client_port_of_the_latest_setup() -> None:
    async with serving(CAMERA) as server:
        client = await Client.connect(server.url, robot(CAMERA))
        other = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        other.bind(("127.0.0.1", 0))
        other.setblocking(False)
        port = other.getsockname()[1]
        try:
            await client.request(
                "SETUP", CONTROL, [("Transport", f"udp;client_port={port};mode=read")]
            )
            await client.request("GO", CONTROL)
            datagram = await asyncio.wait_for(asyncio.get_running_loop().sock_recv(other, 65536), 2)
            packet = pull_packet(datagram)
            assert len(packet.payloads) >= 1  # R-RCTP-56
        finally:
            other.close()
            await client.close()
