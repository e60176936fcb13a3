"""The state map weighs states by their cases' time (D-FUZZ-5): a state whose prefix waits out
a timer is drawn as many times less, and one hang does not starve a state."""

from __future__ import annotations

import random
from collections import Counter

from rcmlconf.fuzz.statemap import StateMap


def _map(quick: float, slow: float) -> StateMap:
    states = StateMap({"quick": ("k",), "slow": ("k",)})
    for _ in range(20):
        states.record("quick", "k", True, (), quick)
        states.record("slow", "k", True, (), slow)
    return states


def _drawn(states: StateMap) -> Counter[str]:
    rng = random.Random(1)
    return Counter(states.pick(rng)[0] for _ in range(2000))


def test_a_state_a_hundred_times_slower_is_drawn_about_a_hundred_times_less() -> None:
    drawn = _drawn(_map(0.003, 0.3))
    assert drawn["slow"] < drawn["quick"] / 30


def test_states_as_quick_are_drawn_alike() -> None:
    drawn = _drawn(_map(0.003, 0.003))
    assert abs(drawn["slow"] - drawn["quick"]) < 300


def test_one_hang_does_not_starve_its_state() -> None:
    states = _map(0.003, 0.003)
    states.record("quick", "k", True, (), 5.0)
    drawn = _drawn(states)
    assert drawn["quick"] > drawn["slow"] / 2


def test_the_times_are_kept_for_a_resumed_campaign() -> None:
    states = _map(0.003, 0.3)
    again = StateMap(states.kinds)
    again.load(states.to_json())
    assert _drawn(again) == _drawn(states)
    legacy = states.to_json()
    del legacy["took"]  # a state.json written before the times were kept
    StateMap(states.kinds).load(legacy)
