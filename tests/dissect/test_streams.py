"""Streams in captures: loss, reordering, duplicates, gaps and jitter of the data stream and of RSP;
heartbeats and clock offsets; RSP sessions and reliable occurrences."""

from __future__ import annotations

import struct
from pathlib import Path
from typing import Any

import pytest
from support.pcaps import dissect, ipv4_udp, pcap

from rcmlconf.dissect import Options, Severity
from rcmlconf.rctp.datastream.clock import ntp_from_unix
from rcmlconf.rsp.codec import (
    Encryption,
    Header,
    Hello,
    Item,
    MapBody,
    Packet,
    PacketType,
    RspCodec,
    Welcome,
)
from rcmlconf.validate.validator import load_robot_model

CUBO = load_robot_model(
    Path(__file__).parents[2] / "rcmlconf" / "reference" / "robots" / "cubo" / "cubo.rmodel"
)
CLIENT, ROBOT = ("10.0.0.2", 46000), ("10.0.0.7", 7330)
LOCAL, RSP_ROBOT = ("10.0.0.2", 50000), ("10.0.0.7", 7340)
T0 = 1_800_000_000.0
TAG = 0x0BADCAFE


def one_data(sequence: int, tag: int, stamp: int, stream: int, body: bytes) -> bytes:
    return struct.pack(">BBHIQBBH", 2, 1, sequence, tag, stamp, 1, stream, len(body)) + body


# -- the data stream -------------------------------------------------------------------------------


def data_capture(sequences: list[int], delays: list[float] | None = None) -> bytes:
    """The robot's DATA every 20 ms, with these sequence numbers, arriving `delays` late."""
    frames = []
    for index, sequence in enumerate(sequences):
        sent = T0 + 0.02 * index
        delay = delays[index] if delays else 0.001
        datagram = one_data(sequence & 0xFFFF, TAG, ntp_from_unix(sent), 1, b"\0" * 8)
        frames.append((sent + delay, ipv4_udp(ROBOT, CLIENT, datagram)))
    return pcap(sorted(frames, key=lambda frame: frame[0]))


def test_loss_reordering_and_duplicates() -> None:
    sequences = [65530, 65531, 65533, 65532, 65534, 65534, 0, 4, 5, 3]
    (stream,) = dissect(data_capture(sequences)).analysis.streams
    # 65532 and 3 arrive late; 65535, 1 and 2 never: lost; 65534 twice.
    assert (stream.packets, stream.lost, stream.late, stream.duplicates) == (10, 3, 2, 1)
    assert (stream.gaps, stream.largest_gap) == (3, 3)
    assert stream.protocol == "rctp-data"
    assert stream.session == "0badcafe"
    assert stream.rule == "R-RCTP-41"


def test_jitter_is_rfc_3550s() -> None:
    steady = dissect(data_capture(list(range(50)), [0.005] * 50)).analysis.streams[0]
    assert steady.jitter == pytest.approx(0.0, abs=1e-6)
    assert steady.interarrival_mean == pytest.approx(0.02, abs=1e-6)
    delays = [0.005 if i % 2 else 0.007 for i in range(400)]  # |D| = 2 ms every packet
    varying = dissect(data_capture(list(range(400)), delays)).analysis.streams[0]
    assert varying.jitter == pytest.approx(0.002, rel=0.01)


def flow_datagram(
    sequence: int, message: int, operation: int, request_id: int, fields: bytes, tag: int = TAG
) -> bytes:
    body = struct.pack(">BBH", message, operation, request_id) + fields
    return struct.pack(">BBHIQBBH", 2, 1, sequence, tag, 0, 2, 0, len(body)) + body


def test_heartbeats_round_trips_and_clock_offset() -> None:
    frames = []
    for index in range(3):
        sent = T0 + index
        t1 = ntp_from_unix(sent)
        # The robot's clock is 50 ms ahead; 2 ms each way, 1 ms to answer.
        t2, t3 = ntp_from_unix(sent + 0.052), ntp_from_unix(sent + 0.053)
        frames.append(
            (
                sent,
                ipv4_udp(CLIENT, ROBOT, flow_datagram(index, 0, 1, index, struct.pack(">Q", t1))),
            )
        )
        frames.append(
            (
                sent + 0.005,
                ipv4_udp(
                    ROBOT,
                    CLIENT,
                    flow_datagram(index, 1, 1, index, struct.pack(">QQQ", t1, t2, t3)),
                ),
            )
        )
    analysis = dissect(pcap(frames)).analysis
    (beats,) = analysis.heartbeats
    assert (beats.requests, beats.answered) == (3, 3)
    assert beats.round_trip == pytest.approx((0.005, 0.005, 0.005), abs=1e-6)
    assert beats.clock is not None
    assert beats.clock.offset == pytest.approx(0.050, abs=1e-6)
    assert beats.clock.delay == pytest.approx(0.004, abs=1e-6)
    assert not analysis.findings


def test_heartbeat_ack_that_does_not_echo_t1() -> None:
    frames = [
        (T0, ipv4_udp(CLIENT, ROBOT, flow_datagram(1, 0, 1, 9, struct.pack(">Q", 5)))),
        (
            T0 + 0.01,
            ipv4_udp(ROBOT, CLIENT, flow_datagram(1, 1, 1, 9, struct.pack(">QQQ", 6, 7, 8))),
        ),
    ]
    assert "R-RCTP-48" in dissect(pcap(frames)).rules()


def test_a_flow_request_never_answered() -> None:
    frames = [(T0, ipv4_udp(CLIENT, ROBOT, flow_datagram(1, 0, 2, 3, b"\x01")))]
    frames.append((T0 + 2, ipv4_udp(CLIENT, ROBOT, one_data(2, TAG, 0, 1, b""))))
    findings = dissect(pcap(frames)).analysis.findings
    assert [(f.severity, f.rule) for f in findings] == [(Severity.WARNING, "R-RCTP-46")]


def test_a_malformed_datagram_is_located_in_the_file() -> None:
    datagram = one_data(1, TAG, 0, 1, b"abcd")[:-1]  # a body length past the end
    data = pcap([(T0, ipv4_udp(CLIENT, ROBOT, datagram))])
    dissected = dissect(data)
    (record,) = dissected.records
    assert record.malformed is not None
    assert record.malformed.offset == 18
    assert record.malformed.file_offset == 24 + 16 + 28 + 18
    assert data[record.malformed.file_offset : record.malformed.file_offset + 2] == b"\x00\x04"
    assert dissected.analysis.errors == 1


# -- RSP -------------------------------------------------------------------------------------------

CODEC = RspCodec(CUBO)
SESSION = 0xA1B2C3D4E5F6
NONCE = bytes(range(16))


def rsp(
    kind: PacketType,
    sequence: int,
    body: Any,
    session: int = SESSION,
    stamp: int = 0,
    buffer: int = 0,
) -> bytes:
    header = Header(1, 1, Encryption.NONE, kind, sequence, stamp, session, 0, buffer)
    return CODEC.push_packet(Packet(header, body))


def rsp_capture(packets: list[tuple[float, bool, bytes]]) -> bytes:
    """(time, from the robot, datagram) each."""
    return pcap(
        [
            (
                T0 + at,
                ipv4_udp(RSP_ROBOT, LOCAL, data) if robot else ipv4_udp(LOCAL, RSP_ROBOT, data),
            )
            for at, robot, data in packets
        ]
    )


MOTION = {"duration": 100, "leftArm": 0, "rightArm": 0, "headTilt": 0}


def test_an_rsp_session_with_retransmissions() -> None:
    packets = [
        (0.000, False, rsp(PacketType.HELLO, 0, Hello(NONCE, 20), session=0)),
        (0.250, False, rsp(PacketType.HELLO, 1, Hello(NONCE, 20), session=0)),
        (0.252, True, rsp(PacketType.WELCOME, 0, Welcome(NONCE, NONCE, 20), buffer=16)),
        # a memory command, sent again after its timeout, then acknowledged
        (0.260, False, rsp(PacketType.DOWNLINK, 2, MapBody((Item(23, 0, MOTION),)), stamp=260)),
        (0.300, True, rsp(PacketType.UPLINK, 1, MapBody(()), stamp=48, buffer=16)),
        (0.460, False, rsp(PacketType.DOWNLINK, 3, MapBody((Item(23, 0, MOTION),)), stamp=460)),
        (0.461, True, rsp(PacketType.ACK, 2, MapBody((Item(23, 0),)), stamp=209, buffer=15)),
        # a lost DOWNLINK (4) and a duplicated UPLINK
        (0.480, False, rsp(PacketType.DOWNLINK, 5, MapBody(()), stamp=480)),
        (0.500, True, rsp(PacketType.UPLINK, 3, MapBody(()), stamp=248, buffer=15)),
        (0.501, True, rsp(PacketType.UPLINK, 3, MapBody(()), stamp=248, buffer=15)),
        (0.520, False, rsp(PacketType.BYE, 6, _bye())),
    ]
    with_model = dissect(rsp_capture(packets), Options(rsp_model=CUBO)).analysis
    (session,) = with_model.rsp_sessions
    assert session.session == f"{SESSION:012x}"
    assert session.handshake == pytest.approx(0.252, abs=1e-6)
    assert session.hellos == 2
    assert session.ended == "CLOSED by the local system"
    assert (session.occurrences, session.repeated, session.resends, session.acknowledged) == (
        1,
        1,
        1,
        1,
    )
    assert session.ack_time == pytest.approx((0.201, 0.201, 0.201), abs=1e-6)
    local, robot = sorted(with_model.streams, key=lambda s: s.source)
    assert (local.packets, local.lost) == (6, 1)  # HELLOs 0, 1 and DOWNLINKs 2, 3, 5, BYE 6
    assert (robot.packets, robot.duplicates) == (5, 1)
    assert not [f for f in with_model.findings if f.severity is Severity.ERROR]
    # Without the model: the same streams and session, but no occurrences.
    without = dissect(rsp_capture(packets)).analysis
    assert [s.packets for s in without.streams] == [s.packets for s in with_model.streams]
    assert without.rsp_sessions[0].occurrences == 0


def _bye() -> Any:
    from rcmlconf.rsp.codec import Bye, ByeReason

    return Bye(ByeReason.CLOSED)


def test_rsp_header_faults_are_findings() -> None:
    other_model = bytearray(rsp(PacketType.DOWNLINK, 2, MapBody(())))
    struct.pack_into(">H", other_model, 1, 2)
    packets = [
        (0.0, False, rsp(PacketType.HELLO, 0, Hello(NONCE, 20), session=0)),
        (0.01, True, rsp(PacketType.WELCOME, 0, Welcome(NONCE, NONCE, 20), buffer=16)),
        (0.02, False, bytes(other_model)),
        (0.03, False, b"\x01\x00"),
    ]
    analysis = dissect(rsp_capture(packets)).analysis
    rules = [(f.severity, f.rule) for f in analysis.findings]
    assert (Severity.ERROR, "R-RSP-13") in rules
    assert rules.count((Severity.ERROR, "R-RSP-13")) == 2  # other model; a header cut short


def test_encrypted_bodies_stay_bytes() -> None:
    header = Header(1, 1, Encryption.AES_256_GCM, PacketType.UPLINK, 1, 0, SESSION, 0, 16)
    data = CODEC.push_header(header) + b"\x99" * 24
    (record,) = dissect(rsp_capture([(0.0, True, data)]), Options(rsp_model=CUBO)).records
    assert record.malformed is None
    assert record.value.body == b"\x99" * 24
