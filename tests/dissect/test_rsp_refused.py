"""A REFUSED echoes the model ID of the HELLO it answers (D-RSP-12): read with one robot's model,
a REFUSED of another model's ID is no malformed packet (found by `rcmlconf fuzz`)."""

from __future__ import annotations

from support.pcaps import dissect, ipv4_udp, pcap

from rcmlconf.conformance.targets import REFERENCE_RMODEL
from rcmlconf.dissect import Options, Severity
from rcmlconf.rsp.codec import Encryption, PacketType
from rcmlconf.rsp.codec.header import HEADER, VERSION
from rcmlconf.validate.validator import load_robot_model

LOCAL, ROBOT = ("10.0.0.2", 40000), ("10.0.0.7", 7340)


def packet(kind: PacketType, model_id: int, body: bytes, last: int = 0, buffer: int = 0) -> bytes:
    head = HEADER.pack(VERSION, model_id, Encryption.NONE, kind, 0, 0, 0, 0, last, buffer)
    return head + body


def test_a_refused_of_another_model_is_read() -> None:
    model = load_robot_model(REFERENCE_RMODEL)
    hello = packet(PacketType.HELLO, 65535, bytes(16) + (20).to_bytes(2, "big"))
    refused = packet(PacketType.REFUSED, 65535, bytes([1]), buffer=model.command_buffers)
    frames = [(1.0, ipv4_udp(LOCAL, ROBOT, hello)), (1.01, ipv4_udp(ROBOT, LOCAL, refused))]
    dissected = dissect(pcap(frames), Options(rsp_model=model))
    kinds = [r.kind for r in dissected.records]
    assert kinds[-1] == "REFUSED", kinds
    errors = [f for f in dissected.analysis.findings if f.severity is Severity.ERROR]
    assert all(f.message != len(dissected.records) for f in errors), errors
