"""Positions resolved in one pass agree with counting from the start, in any text."""

from __future__ import annotations

from hypothesis import given
from hypothesis import strategies as st

from rcmlconf.markup.document import find_entity_references
from rcmlconf.markup.locate import SourceMap
from rcmlconf.markup.prolog import text_position

pieces = ["a", "é", "日", "\n", " ", "<", "&x;", "&lt;", "<!-- &y; -->", "\U0001f916"]
texts = st.lists(st.sampled_from(pieces), max_size=80).map("".join)


@given(texts, st.data())
def test_positions_in_one_pass_equal_positions_one_by_one(text: str, data: st.DataObject) -> None:
    source = text.encode()
    # offsets at character boundaries, ascending, repeats allowed
    boundaries = sorted({len(text[:i].encode()) for i in range(len(text) + 1)})
    offsets = sorted(data.draw(st.lists(st.sampled_from(boundaries), max_size=20)))
    found = SourceMap(source).positions(offsets)
    expected = [text_position(text, len(source[:o].decode())) for o in offsets]
    assert found == expected


@given(texts)
def test_entity_references_point_at_their_ampersand(text: str) -> None:
    lines = text.split("\n")
    for reference in find_entity_references(text):
        assert lines[reference.line - 1][reference.column - 1 :].startswith(f"&{reference.name};")
