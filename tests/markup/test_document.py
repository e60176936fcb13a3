"""Parsing under the XML profile: hostile input is refused, positions are exact, nothing escapes."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st
from support.xml_vectors import XML_VECTORS, xml_vectors

from rcmlconf.markup.document import XmlDocument, XmlElement, parse_document
from rcmlconf.markup.failure import MAX_DOCUMENT_BYTES, ParseFailure
from rcmlconf.validate import Validator


def parsed(text: str | bytes) -> XmlDocument:
    document = parse_document(text.encode() if isinstance(text, str) else text)
    assert isinstance(document, XmlDocument), document
    return document


def failure(data: bytes) -> ParseFailure:
    result = parse_document(data)
    assert isinstance(result, ParseFailure), result
    return result


def test_oversized_documents_are_refused_unread() -> None:
    head = b'<rcml version="2.0" site="rctp://r">'
    data = head + b" " * (MAX_DOCUMENT_BYTES - len(head) - len(b"</rcml>") + 1) + b"</rcml>"
    assert len(data) == MAX_DOCUMENT_BYTES + 1
    assert failure(data).rule == "R-XML-5"
    assert Validator().validate_bytes(data, "big.rcml").diagnostics[0].rule == "R-XML-5"


def test_a_document_of_exactly_the_limit_is_read() -> None:
    head = b'<rcml version="2.0" site="rctp://r">'
    data = head + b" " * (MAX_DOCUMENT_BYTES - len(head) - len(b"</rcml>")) + b"</rcml>"
    assert parsed(data).root.tag == "rcml"


def test_the_entities_of_an_internal_subset_are_never_expanded() -> None:
    laughs = "".join(f'<!ENTITY l{i} "{f"&l{i - 1};" * 10}">' for i in range(1, 10))
    data = f'<!DOCTYPE rcml [<!ENTITY l0 "lol">{laughs}]><rcml title="&l9;"/>'.encode()
    found = failure(data)
    assert (found.rule, found.line, found.column) == ("R-XML-2", 1, 16)


def test_an_internal_subset_after_comments_and_a_public_id_is_found() -> None:
    data = (
        b'<?xml version="1.0"?><!-- [ --><?pi [?>\n'
        b'<!DOCTYPE rcml PUBLIC "-//x [//" "r.dtd"\n [ ]><rcml/>'
    )
    found = failure(data)
    assert (found.rule, found.line, found.column) == ("R-XML-2", 3, 2)


def test_depth_256_is_read_and_257_refused() -> None:
    def nested(depth: int) -> bytes:
        return b"<a>" * depth + b"</a>" * depth

    assert isinstance(parse_document(nested(256)), XmlDocument)
    assert failure(nested(257)).rule == "R-XML-6"


def test_extensions_are_left_out_of_the_tree() -> None:
    document = parsed('<rcml xmlns:x="urn:x" x:a="1"><x:e><group/></x:e><group name="g"/></rcml>')
    root = document.root
    assert [child.tag for child in root.children] == ["group"]
    assert root.attrs == {"urn:x}a": "1"}


def test_text_is_noticed_only_where_it_is_not_whitespace() -> None:
    root = parsed("<rcml>\n  <group>x</group><group> \t\n</group></rcml>").root
    assert [child.has_text for child in root.children] == [True, False]
    assert not root.has_text


@pytest.mark.parametrize("encoding", ["utf-8", "utf-16", "utf-16-le", "shift_jis", "euc-jp"])
def test_columns_count_characters_in_every_encoding(encoding: str) -> None:
    declared = "UTF-16" if encoding.startswith("utf-16") else encoding
    text = f'<?xml version="1.0" encoding="{declared}"?>\n<rcml title="日本語"><group/></rcml>'
    data = text.encode(encoding)
    if encoding == "utf-16-le":
        data = b"\xff\xfe" + data
    document = parsed(data)
    group = document.root.children[0]
    assert document.source.position(group.offset) == (2, 19)
    assert document.root.attrs["title"] == "日本語"


def test_well_formedness_errors_are_libxml2s_first() -> None:
    found = failure(b'<rcml a="1"b="2"/>')
    assert (found.line, found.column, found.message) == (1, 12, "attributes construct error")
    assert found.hint == "missing whitespace between attributes"


@pytest.mark.parametrize(
    ("data", "hint"),
    [
        (b"<rcml a=1/>", "quoted"),
        (b'<rcml a="1" a="2"/>', "once"),
        (b"<rcml><link></rcml>", "<link> opened on line 1 is not closed"),
        (b'<rcml a="x & y"/>', "&amp;"),
        (b'<rcml a="<"/>', "&lt;"),
        (b"<rcml/><rcml/>", "one root"),
        (b"", "no XML element"),
        (b"<x:rcml/>", "xmlns:prefix"),
    ],
)
def test_well_formedness_errors_come_with_a_hint(data: bytes, hint: str) -> None:
    found = failure(data)
    assert found.rule == "R-XML-1"
    assert found.hint is not None
    assert hint in found.hint


def test_undeclared_entities_are_found_when_a_dtd_is_named() -> None:
    document = parsed(
        '<!DOCTYPE rcml SYSTEM "rcml.dtd">\n<rcml a="&x;"><!-- &y; -->&z;&lt;&#38;</rcml>'
    )
    found = [(r.name, r.line, r.column) for r in document.entity_references]
    assert found == [("x", 2, 10), ("z", 2, 27)]


# -- nothing but a finding escapes ---------------------------------------------------------------

SEEDS = [v.path.read_bytes() for v in xml_vectors()]


@given(st.binary(max_size=300))
def test_random_bytes_give_a_document_or_a_failure(data: bytes) -> None:
    assert isinstance(parse_document(data), XmlDocument | ParseFailure)


@st.composite
def mutated(draw: st.DrawFn) -> bytes:
    data = bytearray(draw(st.sampled_from(SEEDS)))
    for _ in range(draw(st.integers(1, 8))):
        at = draw(st.integers(0, len(data)))
        action = draw(st.sampled_from(["flip", "cut", "insert"]))
        if action == "flip" and at < len(data):
            data[at] = draw(st.integers(0, 255))
        elif action == "cut":
            del data[at : at + draw(st.integers(1, 40))]
        else:
            data[at:at] = draw(
                st.sampled_from(
                    [
                        b"<",
                        b">",
                        b'"',
                        b"&",
                        b"/",
                        b"<data/>",
                        b"]]>",
                        b"<!DOCTYPE r [",
                        b"\x00",
                        b"\xff",
                        b'xmlns:x="urn:x" ',
                        b"x:",
                        b"&#xA0;",
                        b"&x;",
                        b"\xc2\xa0",
                    ]
                )
            )
    return bytes(data)


@given(mutated(), st.sampled_from(["x.rcml", "x.rxid"]))
def test_mutated_vectors_give_located_diagnostics(data: bytes, name: str) -> None:
    report = Validator().validate_bytes(data, name, XML_VECTORS / "valid", "." + name[2:])
    lines = data.count(b"\n") + 1
    for diagnostic in report.diagnostics:
        assert 1 <= diagnostic.line <= lines + 1
        assert diagnostic.column >= 1


def test_elements_know_where_they_start() -> None:
    document = parsed('<rcml>\n  <group name="a"\n   permission="r"><access/></group></rcml>')
    group = document.root.children[0]
    access: XmlElement = group.children[0]
    assert document.source.position(group.offset) == (2, 3)
    assert document.source.position(
        document.source.attribute_offset(group.offset, "permission")
    ) == (3, 4)
    assert document.source.position(access.offset) == (3, 19)
