"""The server's and the client's sessions wired in memory: no sockets, time by hand."""

from __future__ import annotations

from support.robots import CAMERA, robot

from rcmlconf.rctp.datastream.packets import DataPayload, pull_packet
from rcmlconf.reference.client.session import Answered, ClientEvent, ClientSession
from rcmlconf.reference.drivers import choose_driver
from rcmlconf.reference.server.robot import Robot
from rcmlconf.reference.server.session import ServerSession

CLIENT = ("127.0.0.1", 40000)
SERVER = ("127.0.0.1", 7330)
CONTROL = "/stream/control"


class Wire:
    def __init__(self) -> None:
        model = robot(CAMERA)
        self.robot = Robot(model, choose_driver("auto", model), 0.0, data_port=SERVER[1])
        self.server = ServerSession(self.robot, CLIENT, 0.0)
        self.client = ClientSession(model, SERVER[0], 0.0)

    def ask(self, method: str, path: str, headers: list[tuple[str, str]] | None = None) -> int:
        self.client.send(method, path, headers or [], now=0.0)
        self.server.receive_data(self.client.data_to_send(), 0.0)
        self.client.receive_data(self.server.data_to_send(), 0.0)
        answers = [e for e in events(self.client) if isinstance(e, Answered)]
        assert len(answers) == 1
        assert answers[0].problem is None
        return answers[0].response.status


def events(client: ClientSession) -> list[ClientEvent]:
    found = []
    while (event := client.next_event()) is not None:
        found.append(event)
    return found


def test_a_write_stream_waits_for_values_without_spinning() -> None:
    wire = Wire()
    assert wire.ask("CONNECT", "/camera") == 200
    assert wire.ask("ACQUIRE", "/stream") == 200
    transport = [("Transport", f"udp;client_port={CLIENT[1]};mode=write")]
    assert wire.ask("SETUP", CONTROL, transport) == 200
    assert wire.ask("GO", CONTROL) == 200
    client = wire.client
    client.handle_timer(0.0)
    datagrams, _ = client.datagrams_to_send(0.0)
    assert [
        p
        for d in datagrams
        for p in pull_packet(d).payloads
        if p.__class__.__name__ == "DataPayload"
    ] == []
    timer = client.get_timer()
    assert timer is not None
    assert timer > 0.0  # the beat moved on: no busy loop while nothing is written
    client.write_values(CONTROL, {"pan": 10, "tilt": 0, "zoom": 0, "focus": 0})
    client.handle_timer(timer)
    datagrams, peer = client.datagrams_to_send(timer)
    assert peer == SERVER
    sent = [p for d in datagrams for p in pull_packet(d).payloads]
    assert any(isinstance(p, DataPayload) for p in sent)
    wire.server.receive_datagram(datagrams[-1], CLIENT, timer)  # pan 10 is the set point now
    wire.robot.handle_timer(timer + 0.1)
    assert wire.robot.driver.values()["/stream/control/pan"] > 0  # the camera turns toward it
