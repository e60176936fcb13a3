"""Delta debugging finds what fires, and the case files read back what they wrote."""

from __future__ import annotations

from hypothesis import given
from hypothesis import strategies as st

from rcmlconf.fuzz.minimise import _Budget, ddmin, minimise
from rcmlconf.fuzz.steps import Step, TestCase

steps = st.builds(
    Step,
    st.sampled_from(["control", "data"]),
    st.binary(max_size=40),
    st.sampled_from(["prefix", "cseq", "bytes", "data-tag", "push-body"]),
    st.booleans(),
    st.binary(max_size=20),  # a client's step's origin (D-FUZZ-8)
)
cases = st.builds(
    TestCase,
    st.sampled_from(["session", "playing"]),
    st.tuples(steps),
    st.lists(steps, max_size=5).map(tuple),
    st.lists(st.text(max_size=8), max_size=3).map(tuple),
)


@given(st.lists(st.integers(0, 50), min_size=1, max_size=40, unique=True), st.data())
def test_ddmin_keeps_exactly_what_a_monotone_oracle_needs(
    items: list[int], data: st.DataObject
) -> None:
    needed = set(data.draw(st.lists(st.sampled_from(items), min_size=1, max_size=4)))
    found = ddmin(items, lambda kept: needed <= set(kept), _Budget(10_000))
    assert set(found) == needed
    assert [x for x in items if x in found] == found  # the order is kept


@given(cases)
def test_a_case_reads_back_what_it_wrote(case: TestCase) -> None:
    assert TestCase.from_json(case.to_json()) == case


def test_minimise_cuts_steps_then_bytes() -> None:
    noise = Step("control", b"READ / RCTP/2.0\r\n\r\n", "cseq")
    culprit = Step("control", b"xxCONTENT-LENGTH: +1yy", "content-length")
    case = TestCase("session", (), (noise, culprit, noise))
    small = minimise(case, lambda c: any(b"+" in s.data for s in c.steps))
    assert small.steps == (Step("control", b"+", "content-length"),)
