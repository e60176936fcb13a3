"""The privilege table (D-RCTP-16): whatever the order of requests, no two sessions overlap."""

from __future__ import annotations

from hypothesis import given
from hypothesis import strategies as st

from rcmlconf.rcml.paths import is_within
from rcmlconf.reference.server.privileges import Privileges

PATHS = ["/", "/a", "/a/b", "/a/b/c", "/a/bc", "/d", "/d/e"]
SESSIONS = ["s1", "s2", "s3"]
steps = st.lists(
    st.tuples(
        st.sampled_from(["acquire", "release", "release_all"]),
        st.sampled_from(SESSIONS),
        st.sampled_from(PATHS),
    ),
    max_size=40,
)


def overlap(one: str, other: str) -> bool:
    return is_within(one, other) or is_within(other, one)


@given(steps)
def test_no_two_sessions_ever_hold_overlapping_paths(plan: list[tuple[str, str, str]]) -> None:
    table = Privileges()
    for action, session, path in plan:
        if action == "acquire":
            others = [p for s in SESSIONS if s != session for p in table.held_by(s)]
            granted = table.acquire(session, path)
            assert granted == (not any(overlap(path, held) for held in others))  # R-RCTP-33
            if granted:
                assert table.covers(session, path)
        elif action == "release":
            held = path in table.held_by(session)
            assert table.release(session, path) == held  # R-RCTP-35
        else:
            table.release_all(session)
            assert table.held_by(session) == ()
        held = [(s, p) for s in SESSIONS for p in table.held_by(s)]
        for s1, p1 in held:
            for s2, p2 in held:
                assert s1 == s2 or not overlap(p1, p2)  # R-RCTP-37


def test_a_prefix_that_is_not_a_parent_does_not_overlap() -> None:
    table = Privileges()
    assert table.acquire("s1", "/a/b")
    assert table.acquire("s2", "/a/bc")  # /a/bc is not below /a/b
    assert table.holder("/a/b/c") == "s1"
    assert table.holder("/a") is None


def test_acquiring_above_what_is_held_takes_it_in() -> None:
    table = Privileges()
    assert table.acquire("s1", "/a/b")
    assert table.acquire("s1", "/a/b/c")  # below: changes nothing
    assert table.held_by("s1") == ("/a/b",)
    assert table.acquire("s1", "/a")
    assert table.held_by("s1") == ("/a",)
    assert not table.release("s1", "/a/b")  # no longer held by itself
