"""Occurrences and selective retransmission (D-RSP-16, D-RSP-17), with time by hand."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from rcmlconf.rsp.model import Device, DeviceKind
from rcmlconf.rsp.reliable import (
    EVENT_REPEATS,
    MAX_RTO,
    EventRepeater,
    ReceivedIds,
    ReliableSender,
    RetransmissionTimer,
)

T = 0.02
COMMAND = Device(0, "irFire", DeviceKind.COMMAND)
MEMORY = Device(1, "motion", DeviceKind.MEMORY_COMMAND)
EVENT = Device(2, "button", DeviceKind.EVENT)


def always(device: Device) -> bool:
    return True


def test_the_timer_follows_rfc_6298() -> None:
    timer = RetransmissionTimer(T)
    assert timer.rto == pytest.approx(10 * T)  # before any round trip
    timer.sample(0.1)
    assert (timer.srtt, timer.rttvar) == (0.1, 0.05)
    assert timer.rto == pytest.approx(0.3)
    timer.sample(0.1)
    assert timer.rttvar == pytest.approx(0.0375)
    assert timer.rto == pytest.approx(0.1 + 4 * 0.0375)
    for _ in range(10):
        timer.back_off()
    assert timer.rto == MAX_RTO
    fast = RetransmissionTimer(T)
    fast.sample(0.001)
    assert fast.rto == pytest.approx(2 * T)  # never below two periods


def test_a_command_rides_every_packet_until_acknowledged() -> None:
    sender = ReliableSender(256, T)
    first = sender.issue(COMMAND, {"code": 1})
    second = sender.issue(COMMAND, {"code": 2})
    assert (first, second) == (0, 1)
    for beat in range(3):
        (carried,) = sender.due(beat * T, always)
        assert carried.id == 0  # the second waits for the first's ACK (R-RSP-29)
        sender.sent([carried], beat * T)
    assert sender.acknowledged(COMMAND.position, 1, 0.07) is None  # not the one in flight
    done = sender.acknowledged(COMMAND.position, 0, 0.07)
    assert done is not None
    assert done.sends == 3
    assert sender.timer.srtt is None  # sent three times: no round trip measured (Karn)
    (carried,) = sender.due(0.08, always)
    assert carried.id == 1


def test_a_memory_command_waits_a_timeout_between_sends() -> None:
    sender = ReliableSender(256, T)
    sender.issue(MEMORY, {"duration": 100})
    assert sender.due(0.0, lambda device: False) == []  # no free buffer: it does not start
    (carried,) = sender.due(0.0, always)
    sender.sent([carried], 0.0)
    rto = sender.timer.rto
    assert sender.get_timer() == pytest.approx(rto)
    assert sender.due(rto - 0.001, always) == []
    assert sender.due(rto, always) == [carried]
    sender.sent([carried], rto)
    assert sender.timer.rto == pytest.approx(2 * rto)  # backed off
    assert sender.acknowledged(MEMORY.position, 0, rto + 0.01) is carried
    assert sender.get_timer() is None


def test_a_round_trip_is_measured_from_an_occurrence_sent_once() -> None:
    sender = ReliableSender(256, T)
    sender.issue(MEMORY, {"duration": 100})
    (carried,) = sender.due(1.0, always)
    sender.sent([carried], 1.0)
    sender.acknowledged(MEMORY.position, 0, 1.05)
    assert sender.timer.srtt == pytest.approx(0.05)


@pytest.mark.parametrize("space", [256, 65536])
def test_ids_are_new_once_and_wrap(space: int) -> None:
    ids = ReceivedIds(space)
    assert ids.take(3, space - 1)
    assert not ids.take(3, space - 1)  # repeated
    assert ids.take(3, 0)  # wrapped: new
    assert not ids.is_new(3, space - 2)  # older
    assert ids.take(4, space - 2)  # another device counts on its own


@given(st.lists(st.integers(1, 40), min_size=1, max_size=50))
def test_repeats_in_any_order_are_taken_once(sends: list[int]) -> None:
    """Each occurrence sent several times, interleaved with repeats of the one before."""
    ids = ReceivedIds(256)
    taken = []
    for current in range(len(sends)):
        for _ in range(sends[current]):
            for candidate in range(max(current - 1, 0), current + 1):  # late repeats, then it
                if ids.take(7, candidate % 256):
                    taken.append(candidate % 256)
    assert taken == [n % 256 for n in range(len(sends))]


def test_an_event_rides_three_packets_and_the_next_waits() -> None:
    repeater = EventRepeater(256)
    repeater.occur(EVENT, {"pressed": True})
    repeater.occur(EVENT, {"pressed": False})
    rides = [[o.id for o in repeater.ride()] for _ in range(2 * EVENT_REPEATS + 1)]
    assert rides == [[0]] * EVENT_REPEATS + [[1]] * EVENT_REPEATS + [[]]
