"""Random documents built from the languages' own names: the validator never raises, and every
finding is located and names a requirement of specs/."""

from __future__ import annotations

from xml.sax.saxutils import quoteattr

from hypothesis import given
from hypothesis import strategies as st
from support.xml_vectors import XML_VECTORS

from rcmlconf.rcml.schema import ELEMENTS as RCML_ELEMENTS
from rcmlconf.rxid.schema import ELEMENTS as RXID_ELEMENTS
from rcmlconf.specs import requirements
from rcmlconf.validate import Validator

KNOWN = requirements()
#: One validator for all examples: the RCML files sessions name are read once.
VALIDATOR = Validator()
TAGS = sorted({*RCML_ELEMENTS, *RXID_ELEMENTS, "dta", "x:data", "y:group"})
ATTRIBUTES = sorted(
    {
        name
        for table in (RCML_ELEMENTS, RXID_ELEMENTS)
        for spec in table.values()
        for name in spec.attributes
    }
    | {"typ", "x:a", "xml:lang"}
)
VALUES = st.sampled_from(
    [
        "",
        "2.0",
        "rctp://r",
        "int",
        "string",
        "rw",
        "r",
        "none",
        "stream",
        "event",
        "16e-3",
        "0",
        "-1",
        "INF",
        "1" * 30,
        "/a",
        "/a/b",
        "a",
        "testbot.rcml",
        "../valid/testbot.rcml",
        "http://x/y.rcml",
        "true",
        "go",
        "acquire",
        "é",
        "\u00a0",
        "a b",
        "x" * 300,
    ]
)


@st.composite
def element(draw: st.DrawFn, depth: int = 0) -> str:
    tag = draw(st.sampled_from(TAGS))
    attributes = draw(st.dictionaries(st.sampled_from(ATTRIBUTES), VALUES, max_size=4))
    text = "".join(f" {name}={quoteattr(value)}" for name, value in attributes.items())
    children = draw(st.lists(element(depth + 1), max_size=3)) if depth < 2 else []
    content = draw(st.sampled_from(["", " ", "text", "&#xA0;"])) + "".join(children)
    return f"<{tag}{text}>{content}</{tag}>"


@st.composite
def document(draw: st.DrawFn) -> str:
    root = draw(st.sampled_from(["rcml", "rxid", "x:rcml", "robot"]))
    body = "".join(draw(st.lists(element(), max_size=4)))
    version = draw(st.sampled_from(['version="2.0" site="rctp://r"', "", 'version="1"']))
    namespaces = 'xmlns:x="urn:x" xmlns:y="urn:y"'
    return f"<{root} {namespaces} {version}>{body}</{root}>"


@given(document(), st.sampled_from([".rcml", ".rxid"]))
def test_random_documents_give_located_findings(text: str, suffix: str) -> None:
    report = VALIDATOR.validate_bytes(text.encode(), "fuzz" + suffix, XML_VECTORS / "valid", suffix)
    for diagnostic in report.diagnostics:
        assert diagnostic.rule in KNOWN, diagnostic.to_text()
        assert diagnostic.line == 1, diagnostic.to_text()
        assert 1 <= diagnostic.column <= len(text) + 1, diagnostic.to_text()
