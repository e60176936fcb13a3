"""The console writes lines a terminal shows as they are, whatever names and bytes the input had."""

from __future__ import annotations

import io

from hypothesis import given
from hypothesis import strategies as st

from rcmlconf.cli.console import Output, printable

_CONTROL = {*range(0x09), *range(0x0A, 0x20), *range(0x7F, 0xA0)}


@given(st.text())
def test_printable_leaves_no_control_character_or_surrogate(text: str) -> None:
    shown = printable(text)
    assert not any(ord(c) in _CONTROL or 0xD800 <= ord(c) <= 0xDFFF for c in shown)


@given(st.text(st.characters(blacklist_categories=("Cc", "Cs"))))
def test_printable_text_is_left_as_it_is(text: str) -> None:
    assert printable(text + "\t") == text + "\t"


def test_a_file_name_of_hostile_bytes_is_one_escaped_line() -> None:
    out = io.StringIO()
    Output(stdout=out).out.line([("new\nline\x1b[2J bad\udcff.rcml:1:1: error", "")])
    assert out.getvalue() == "new\\nline\\x1b[2J bad\\xff.rcml:1:1: error\n"


def test_a_batch_of_lines_stays_a_line_each() -> None:
    out = io.StringIO()
    Output(stdout=out).out.lines(["one", "two\r", "three"])
    assert out.getvalue().splitlines() == ["one", "two\\r", "three"]
