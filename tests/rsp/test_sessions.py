"""RSP sessions end to end in memory (specs/rsp.md §2-§4): the sans-IO local system and robot on a
simulated clock, with seeded loss, duplication and reordering between them."""

from __future__ import annotations

from dataclasses import replace

import pytest
from support.rsp_models import robot_model
from support.rsp_pair import LOCAL_ADDR, Pair, open_pair

from rcmlconf.rsp.codec import ByeReason, Encryption, MapBody, PacketType, RefusedReason
from rcmlconf.rsp.session import events
from rcmlconf.rsp.session.local import HELLO_RETRIES, LocalEndpoint
from rcmlconf.rsp.session.robot import RobotEndpoint

PSK = bytes(range(32))
MOTION = {"duration": 100, "leftArm": 0, "rightArm": 0, "headTilt": 0}
POSE = {"x": 1.0, "y": 2.0, "heading": 0.5}


def of(kind: type, found: list[events.Event]) -> list:  # type: ignore[type-arg]
    return [event for event in found if isinstance(event, kind)]


def opened(pair: Pair) -> Pair:
    """The pair once its session is open (HELLOs may be lost: they are repeated, D-RSP-12)."""
    for _ in range(30):
        pair.run_until(pair.now + 0.05)
        if of(events.SessionOpened, pair.local_events):
            break
    assert of(events.SessionOpened, pair.local_events)
    return pair


def test_a_session_opens_and_states_flow_both_ways() -> None:
    pair = opened(open_pair(robot_model()))
    pair.local.write("leftWheel", {"speed": 100})
    pair.local.set_active("base", True)
    pair.local.set_active("position", True)
    pair.robot.set_state("position", POSE)
    pair.run_until(pair.now + 0.2)
    assert pair.robot.effectors(pair.now)["leftWheel"] == {"speed": 100}
    states = of(events.StateReceived, pair.local_events)
    assert {s.device for s in states} == {"position"}
    assert len(states) >= 8  # one UPLINK every T = 20 ms
    assert states[-1].values == POSE


def test_the_robot_reports_only_what_was_requested() -> None:
    """R-RSP-23; D-RSP-14: an effector of an inactive module is not applied."""
    pair = opened(open_pair(robot_model()))
    pair.robot.set_state("position", POSE)
    pair.robot.set_state("battery", {"charge": 80})
    pair.local.write("leftWheel", {"speed": 100})  # base is not active
    pair.local.set_active("battery", True)
    pair.run_until(pair.now + 0.2)
    assert {s.device for s in of(events.StateReceived, pair.local_events)} == {"battery"}
    assert pair.robot.effectors(pair.now)["leftWheel"] == {"speed": 0}
    pair.local.set_active("battery", False)
    pair.run_until(pair.now + 0.1)
    settled = len(of(events.StateReceived, pair.local_events))
    pair.run_until(pair.now + 0.2)
    assert len(of(events.StateReceived, pair.local_events)) == settled


def test_the_robot_names_what_the_next_uplink_carries_and_when() -> None:
    """D-RSP-14: requested sensors and monitors, not those of an inactive module; T by PERIOD."""
    robot = RobotEndpoint(robot_model())
    assert robot.reporting() == []
    assert robot.next_beat() is None
    pair = opened(open_pair(robot_model(), robot=robot))
    pair.local.set_active("battery", True)
    pair.local.set_active("leftWheelMonitor", True)  # in base, which is not active
    pair.run_until(pair.now + 0.1)
    assert robot.reporting() == ["battery"]
    pair.local.set_active("base", True)
    pair.run_until(pair.now + 0.1)
    assert sorted(robot.reporting()) == ["battery", "leftWheelMonitor"]
    beat = robot.next_beat()
    assert beat is not None
    assert pair.now < beat <= pair.now + robot.period
    assert pair.local.next_beat() is not None


def test_an_idle_session_stays_alive_on_empty_maps() -> None:
    """D-RSP-13: nothing to set, a packet every 5 periods: silence means loss, not idleness."""
    pair = opened(open_pair(robot_model()))
    pair.run_until(pair.now + 12.0)
    assert not of(events.LinkLost, pair.local_events + pair.robot_events)
    assert not of(events.SessionClosed, pair.local_events + pair.robot_events)


@pytest.mark.parametrize("seed", range(8))
def test_under_loss_duplication_and_reordering_each_occurrence_is_taken_once(seed: int) -> None:
    """R-RSP-25 to R-RSP-30: commands and memory commands executed once each, in order; events
    and memory events delivered once each."""
    model = robot_model()
    pair = opened(open_pair(model, loss=0.2, duplicate=0.2, reorder=0.3, seed=seed))
    pair.local.set_active("serviceButton", True)
    pair.local.set_active("lowBattery", True)
    pair.run_until(pair.now + 0.3)  # the requests reach the robot
    commands = [pair.local.issue("irFire", {"code": n}) for n in range(10)]
    motions = [pair.local.issue("motion", {**MOTION, "duration": n + 1}) for n in range(30)]
    raised = []
    executed = []
    for step in range(40):
        pair.run_until(pair.now + 0.05)
        if step % 4 == 0:
            raised.append(pair.robot.occur("serviceButton", {"pressed": step % 8 == 0}))
            raised.append(pair.robot.occur("lowBattery", {"charge": step}))
        while (memory := pair.robot.take_memory_command()) is not None:
            executed.append(memory.values["duration"])
    for _ in range(60):  # RTOs back off to 2 s under this much loss (D-RSP-17)
        pair.run_until(pair.now + 0.5)
        while (memory := pair.robot.take_memory_command()) is not None:
            executed.append(memory.values["duration"])
    fired = [e.values["code"] for e in of(events.OccurrenceReceived, pair.robot_events)]
    assert fired == list(range(10)), commands
    assert executed == [n + 1 for n in range(30)], motions
    delivered = of(events.OccurrenceReceived, pair.local_events)
    assert None not in raised
    buttons = [e.id for e in delivered if e.device == "serviceButton"]
    batteries = [e.values["charge"] for e in delivered if e.device == "lowBattery"]
    assert batteries == list(range(0, 40, 4))  # reliable: all of them, in order
    assert len(buttons) == len(set(buttons))  # events: each once (one may be lost in 3 rides)
    assert len(buttons) >= 8


def test_memory_commands_wait_for_free_buffers() -> None:
    """D-RSP-19, R-RSP-31, R-RSP-32: never more in flight than the robot has room for."""
    model = robot_model()
    pair = opened(open_pair(model))
    for n in range(3 * model.command_buffers):
        pair.local.issue("motion", {**MOTION, "duration": n + 1})
    pair.run_until(pair.now + 1.0)
    assert pair.robot.free_buffers == 0
    assert pair.local.latest_free() == 0
    for _ in range(5):
        pair.robot.take_memory_command()
    pair.run_until(pair.now + 3.0)  # the one waiting goes again after its RTO (at most 2 s)
    assert pair.robot.free_buffers == 0  # the five freed were filled again
    pair.local.clear_buffer()
    pair.run_until(pair.now + 3.0)
    taken = pair.robot.take_memory_command()
    assert taken is not None
    assert taken.values["duration"] > model.command_buffers + 5  # older ones were dropped


def test_the_link_lost_stops_the_wheels_and_holds_the_arms() -> None:
    """D-RSP-20, R-RSP-36; R-RSP-22: then the session times out on both sides."""
    pair = opened(open_pair(robot_model()))
    pair.local.set_active("base", True)
    pair.local.set_active("arms", True)
    pair.local.write("leftWheel", {"speed": 300})
    pair.local.write("leftArm", {"angle": 450})
    pair.run_until(pair.now + 0.2)
    assert pair.robot.effectors(pair.now)["leftWheel"] == {"speed": 300}
    pair.loss = 1.0
    pair.run_until(pair.now + 0.6)
    assert of(events.LinkLost, pair.robot_events)
    assert pair.robot.effectors(pair.now)["leftWheel"] == {"speed": 0}
    assert pair.robot.effectors(pair.now)["leftArm"] == {"angle": 450}
    pair.run_until(pair.now + 10.0)
    for side in (pair.local_events, pair.robot_events):
        assert of(events.SessionClosed, side) == [events.SessionClosed(ByeReason.TIMEOUT, False)]


def test_bye_ends_the_session_on_both_sides() -> None:
    pair = opened(open_pair(robot_model()))
    pair.local.close(pair.now)
    pair.run_until(pair.now + 0.1)
    assert of(events.SessionClosed, pair.robot_events) == [
        events.SessionClosed(ByeReason.CLOSED, True)
    ]
    assert pair.robot.session is None


def test_a_new_period_changes_the_robots_pace() -> None:
    """D-RSP-13: PERIOD, sent three times."""
    pair = opened(open_pair(robot_model()))
    pair.local.set_active("position", True)
    pair.robot.set_state("position", POSE)
    pair.local.set_period(0.1, pair.now)
    pair.run_until(pair.now + 0.2)
    before = len(pair.sent_up)
    pair.run_until(pair.now + 1.0)
    assert 9 <= len(pair.sent_up) - before <= 11
    periods = [d for d in pair.sent_down if d[4] == PacketType.PERIOD]
    assert len(periods) == 3


def test_a_hello_without_answer_is_repeated_then_given_up() -> None:
    """D-RSP-12: every 250 ms, five times at most."""
    pair = open_pair(robot_model(), loss=1.0)
    pair.run_until(3.0)
    hellos = [d for d in pair.sent_down if d[4] == PacketType.HELLO]
    assert len(hellos) == 1 + HELLO_RETRIES
    assert [d[5:7] for d in hellos] == [n.to_bytes(2) for n in range(6)]  # new packets
    assert pair.local_events == [events.SessionRefused(None)]


def test_a_repeated_hello_gets_the_same_welcome() -> None:
    model = robot_model()
    robot = RobotEndpoint(model)
    local = LocalEndpoint(model, nonce=b"x" * 16)
    local.connect(0.0)
    (hello,) = local.datagrams_to_send(0.0)
    robot.receive_datagram(hello, LOCAL_ADDR, 0.0)
    local.handle_timer(0.25)
    (again,) = local.datagrams_to_send(0.25)
    robot.receive_datagram(again, LOCAL_ADDR, 0.25)
    (first, _), (second, _) = robot.datagrams_to_send(0.25)
    assert first == second


def refused(local: LocalEndpoint, robot: RobotEndpoint) -> events.Event | None:
    local.connect(0.0)
    (hello,) = local.datagrams_to_send(0.0)
    robot.receive_datagram(hello, LOCAL_ADDR, 0.0)
    ((answer, _),) = robot.datagrams_to_send(0.0)
    local.receive_datagram(answer, 0.0)
    return local.next_event()


def test_a_robot_refuses_a_local_system_of_another_model() -> None:
    """R-RSP-21; D-RSP-12: REFUSED echoes the HELLO's model ID, so the local system reads it."""
    model = robot_model()
    other = replace(model, model_id=2)
    reason = refused(LocalEndpoint(other, nonce=b"x" * 16), RobotEndpoint(model))
    assert reason == events.SessionRefused(RefusedReason.UNKNOWN_MODEL)


def test_a_robot_refuses_an_encryption_it_does_not_offer() -> None:
    """D-RSP-21."""
    model = robot_model()
    local = LocalEndpoint(model, nonce=b"x" * 16, encryption=Encryption.AES_256_GCM, psk=PSK)
    reason = refused(local, RobotEndpoint(model))
    assert reason == events.SessionRefused(RefusedReason.ENCRYPTION_NOT_OFFERED)


def test_a_second_local_system_is_refused_busy() -> None:
    model = robot_model()
    pair = opened(open_pair(model))
    other = LocalEndpoint(model, nonce=b"o" * 16)
    other.connect(pair.now)
    (hello,) = other.datagrams_to_send(pair.now)
    pair.robot.receive_datagram(hello, ("127.0.0.1", 40001), pair.now)
    ((answer, addr),) = pair.robot.datagrams_to_send(pair.now)
    other.receive_datagram(answer, pair.now)
    assert addr == ("127.0.0.1", 40001)
    assert other.next_event() == events.SessionRefused(RefusedReason.BUSY)


@pytest.mark.parametrize("cipher", [Encryption.AES_256_GCM, Encryption.CHACHA20_POLY1305])
def test_an_encrypted_session_runs_and_drops_tampered_packets(cipher: Encryption) -> None:
    """D-RSP-21, R-RSP-37, R-RSP-18."""
    model = robot_model()
    local = LocalEndpoint(model, nonce=b"e" * 16, encryption=cipher, psk=PSK)
    robot = RobotEndpoint(model, encryptions=frozenset({cipher}), psk=PSK)
    pair = opened(open_pair(model, local, robot))
    pair.local.set_active("base", True)
    pair.local.write("leftWheel", {"speed": 120})
    pair.run_until(pair.now + 0.2)
    assert pair.robot.effectors(pair.now)["leftWheel"] == {"speed": 120}
    sealed = pair.sent_down[-1]
    assert b"\x00\x78" not in sealed[20:]  # 120 is not in the clear
    for flip in (3, 7, 20, len(sealed) - 1):  # header (AAD), body, tag
        tampered = bytearray(sealed)
        tampered[flip] ^= 0x01
        pair.robot.receive_datagram(bytes(tampered), LOCAL_ADDR, pair.now)
    drops = of(events.PacketDropped, list(iter(pair.robot.next_event, None)))
    assert len(drops) == 4
    assert {d.rule for d in drops} <= {"R-RSP-18", "R-RSP-13"}


def test_a_hello_with_a_wrong_mac_is_refused_not_authenticated() -> None:
    """R-RSP-38."""
    model = robot_model()
    local = LocalEndpoint(model, nonce=b"e" * 16, encryption=Encryption.AES_256_GCM, psk=PSK)
    robot = RobotEndpoint(
        model, encryptions=frozenset({Encryption.AES_256_GCM}), psk=bytes(reversed(PSK))
    )
    pair = open_pair(model, local, robot)
    pair.run_until(0.1)
    assert pair.local_events == [events.SessionRefused(RefusedReason.NOT_AUTHENTICATED)]
    assert robot.session is None


def test_spoofed_and_replayed_packets_are_dropped() -> None:
    """R-RSP-18: another session ID, another address, a packet seen before."""
    pair = opened(open_pair(robot_model()))
    pair.local.set_active("base", True)
    pair.local.write("leftWheel", {"speed": 50})
    pair.run_until(pair.now + 0.1)
    genuine = pair.sent_down[-1]
    pair.run_until(pair.now + 0.01)  # it has arrived
    spoofed = bytearray(genuine)
    spoofed[5:7] = (int.from_bytes(genuine[5:7]) + 1).to_bytes(2)
    spoofed[11] ^= 0xFF
    for data, addr in (
        (bytes(spoofed), LOCAL_ADDR),
        (genuine, ("127.0.0.1", 40009)),
        (genuine, LOCAL_ADDR),
    ):
        pair.robot.receive_datagram(data, addr, pair.now)
    drops = of(events.PacketDropped, list(iter(pair.robot.next_event, None)))
    assert [d.rule for d in drops] == ["R-RSP-18"] * 3
    assert pair.robot.session is not None


def test_a_packet_of_a_type_its_receiver_is_not_sent_is_dropped_unread() -> None:
    """R-RSP-18 (D-RSP-11): a DOWNLINK reaching the local system, an UPLINK reaching the robot,
    of the session and newer, are dropped before anything of them is taken: the local system's
    free-buffer count stays what the robot said."""
    pair = opened(open_pair(robot_model()))
    pair.run_until(pair.now + 0.1)
    free = pair.local.free_buffers
    down = bytearray(pair.sent_down[-1])
    down[5:7] = (int.from_bytes(down[5:7]) + 1000).to_bytes(2)  # newer than anything seen
    down[19] = 0  # "no buffer free", it would say
    pair.local.receive_datagram(bytes(down), pair.now)
    drops = of(events.PacketDropped, list(iter(pair.local.next_event, None)))
    assert [d.rule for d in drops] == ["R-RSP-18"]
    assert pair.local.free_buffers == free
    pair.robot.receive_datagram(pair.sent_up[-1], LOCAL_ADDR, pair.now)
    drops = of(events.PacketDropped, list(iter(pair.robot.next_event, None)))
    assert [d.rule for d in drops] == ["R-RSP-18"]


def exchange(local: LocalEndpoint, robot: RobotEndpoint, now: float) -> int:
    """One period: the local system's due packets to the robot and the robot's back; how many
    memory commands the local system sent."""
    local.handle_timer(now)
    sent = 0
    for data in local.datagrams_to_send(now):
        header, body = local.codec.pull_packet(data)
        if header.type is PacketType.DOWNLINK and isinstance(body, MapBody):
            sent += sum(1 for item in body.items if item.id is not None)
        robot.receive_datagram(data, LOCAL_ADDR, now)
    for data, _ in robot.datagrams_to_send(now):
        local.receive_datagram(data, now)
    return sent


def test_welcome_and_ack_give_the_free_buffers_too() -> None:
    """D-RSP-19: every robot packet gives its free buffers, WELCOME and ACK too (R-RSP-32): a
    local system that read them from UPLINKs only would overfill the robot's buffer."""
    model = robot_model()
    local, robot = LocalEndpoint(model, nonce=b"n" * 16), RobotEndpoint(model)
    local.connect(0.0)
    for data in local.datagrams_to_send(0.0):
        robot.receive_datagram(data, LOCAL_ADDR, 0.0)
    ((welcome, _),) = robot.datagrams_to_send(0.0)
    local.receive_datagram(welcome[:19] + b"\x00" + welcome[20:], 0.0)  # none free, it says
    local.issue("motion", MOTION)
    assert exchange(local, robot, 0.02) == 0
    local.receive_datagram(welcome, 0.03)  # a repeated WELCOME is no newer: nothing changes
    assert exchange(local, robot, 0.04) == 0
    fresh = LocalEndpoint(model, nonce=b"m" * 16)
    fresh.connect(1.0)
    robot = RobotEndpoint(model)
    for data in fresh.datagrams_to_send(1.0):
        robot.receive_datagram(data, LOCAL_ADDR, 1.0)
    for data, _ in robot.datagrams_to_send(1.0):
        fresh.receive_datagram(data, 1.0)
    for n in range(model.command_buffers + 1):
        fresh.issue("motion", {**MOTION, "duration": n + 1})
    sent = sum(exchange(fresh, robot, 1.0 + 0.02 * k) for k in range(1, 40))
    assert sent == model.command_buffers  # the ACK of the last said none is free
    assert robot.free_buffers == 0


def test_sessions_of_one_model_share_its_codec_and_keep_their_own_maps() -> None:
    """`codec_for`: every endpoint of a model (or of an equal one) in a process uses one codec,
    whose caches (the map last read and written) alternating sessions with other maps share."""
    model = robot_model()
    first = opened(open_pair(model))
    second = opened(open_pair(replace(model)))  # equal, not the same object
    assert first.local.codec is first.robot.codec is second.local.codec is second.robot.codec
    first.local.write("leftWheel", {"speed": 100})
    first.local.set_active("base", True)
    first.local.set_active("position", True)
    first.robot.set_state("position", POSE)
    second.local.set_active("battery", True)
    second.robot.set_state("battery", {"charge": 80})
    second.robot.set_state("position", {**POSE, "x": -3.0})
    for _ in range(20):  # one period of each in turn: every packet's map is the other's last
        first.run_until(first.now + 0.02)
        second.run_until(second.now + 0.02)
    assert first.robot.effectors(first.now)["leftWheel"] == {"speed": 100}
    assert second.robot.effectors(second.now)["leftWheel"] == {"speed": 0}
    assert {s.device for s in of(events.StateReceived, first.local_events)} == {"position"}
    assert of(events.StateReceived, first.local_events)[-1].values == POSE
    assert {s.device for s in of(events.StateReceived, second.local_events)} == {"battery"}
    assert of(events.StateReceived, second.local_events)[-1].values == {"charge": 80}
