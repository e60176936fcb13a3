"""Parse a document under the XML profile (specs/xml.md): screened, bounded, never expanded.

expat (C, in the standard library) builds a light tree of `XmlElement`s: an attribute dict and
the byte offset of each start tag, and nothing else. An lxml tree costs about 2 µs more per element
in proxies and attribute tuples, which on a 100,000-node RCML file is most of the time budget.
libxml2 (lxml) remains the authority on well-formedness errors: when expat rejects a document, it
is parsed again by libxml2 for the exact message and position of the first fatal error.
"""

from __future__ import annotations

import re
import xml.parsers.expat as expat
from dataclasses import dataclass

from rcmlconf.markup.encoding import decode_document, python_codec
from rcmlconf.markup.failure import MAX_DEPTH, MAX_DOCUMENT_BYTES, ParseFailure
from rcmlconf.markup.locate import SourceMap
from rcmlconf.markup.prolog import Doctype, screen_prolog, text_position

#: Namespaced names read `uri}local`; '}' never occurs in a name without a namespace.
NAMESPACE_SEPARATOR = "}"


class XmlElement:
    """One element: its tag, attributes as written, where it starts, and its element children.

    Elements in a namespace other than none (extensions, D-XML-6) are left out of the tree. A
    plain slotted class: one is made per element, and a dataclass costs more to create.
    """

    __slots__ = ("attrs", "children", "has_text", "offset", "tag")

    def __init__(self, tag: str, attrs: dict[str, str], offset: int) -> None:
        self.tag = tag
        self.attrs = attrs
        #: Byte offset of its `<` in the document's UTF-8 source.
        self.offset = offset
        self.children: list[XmlElement] = []
        #: Whether it directly holds character data other than whitespace (R-XML-9).
        self.has_text = False

    def __repr__(self) -> str:
        return f"<XmlElement {self.tag} at byte {self.offset}>"


def display_name(name: str) -> str:
    """A name as people write it: `{uri}local` (Clark notation) for one in a namespace."""
    uri, separator, local = name.rpartition(NAMESPACE_SEPARATOR)
    return f"{{{uri}}}{local}" if separator else name


@dataclass(frozen=True, slots=True)
class EntityReference:
    """A reference to an entity no parser will expand (R-XML-11)."""

    name: str
    line: int
    column: int


@dataclass
class XmlDocument:
    root: XmlElement
    doctype: Doctype | None
    source: SourceMap
    entity_references: tuple[EntityReference, ...] = ()


class _TooDeep(Exception):
    def __init__(self, offset: int) -> None:
        self.offset = offset


def parse_document(data: bytes) -> XmlDocument | ParseFailure:
    if len(data) > MAX_DOCUMENT_BYTES:
        return ParseFailure(
            "R-XML-5",
            1,
            1,
            f"document is {len(data):,} bytes, more than the limit of {MAX_DOCUMENT_BYTES:,}",
        )
    codec = python_codec(data)
    if codec is None:
        return _unknown_encoding(data)
    text = decode_document(data, codec)
    doctype = screen_prolog(text)
    if doctype is not None and doctype.subset_offset is not None:
        line, column = text_position(text, doctype.subset_offset)
        what = "declares entities" if doctype.declares_entities else "is refused"
        return ParseFailure(
            "R-XML-2",
            line,
            column,
            f"internal DTD subset {what}: documents may not declare entities, attribute defaults "
            "or notations, and nothing in them is ever expanded",
            "remove the [ ... ] part of the DOCTYPE",
        )
    # expat is always given UTF-8, so every offset below is into one buffer of known encoding.
    source = data if codec == "utf-8" else text.encode("utf-8")
    try:
        root = _build(source)
    except expat.ExpatError as exc:
        return _syntax_failure(data, exc)
    except _TooDeep as exc:
        line, column = SourceMap(source).position(exc.offset)
        return ParseFailure(
            "R-XML-6", line, column, f"elements nest deeper than {MAX_DEPTH} levels"
        )
    references = find_entity_references(text) if doctype is not None and doctype.system_id else ()
    return XmlDocument(root, doctype, SourceMap(source), references)


def _build(source: bytes) -> XmlElement:
    parser = expat.ParserCreate("UTF-8", NAMESPACE_SEPARATOR)
    parser.buffer_text = True
    # Never read a DTD or an external entity (D-XML-3); expat's default, stated.
    parser.SetParamEntityParsing(expat.XML_PARAM_ENTITY_PARSING_NEVER)
    document = XmlElement("", {}, 0)  # holds the root element as its only child
    stack = [document]
    skipping = 0  # depth inside an extension element

    def start(tag: str, attrs: dict[str, str]) -> None:
        nonlocal skipping
        # Below the root, an element in a namespace is an extension; the root itself stays, to
        # be reported as a language rcmlconf does not know (R-XML-7).
        if skipping or (NAMESPACE_SEPARATOR in tag and len(stack) > 1):
            skipping += 1
            return
        element = XmlElement(tag, attrs, parser.CurrentByteIndex)
        if len(stack) > MAX_DEPTH:
            raise _TooDeep(element.offset)
        stack[-1].children.append(element)
        stack.append(element)

    def end(tag: str) -> None:
        nonlocal skipping
        if skipping:
            skipping -= 1
        else:
            stack.pop()

    def characters(data: str) -> None:
        # XML white space is these four characters; str.isspace() would also pass U+00A0.
        if not skipping and data.strip(" \t\r\n"):
            stack[-1].has_text = True

    parser.StartElementHandler = start
    parser.EndElementHandler = end
    parser.CharacterDataHandler = characters
    try:
        parser.Parse(source, True)
    finally:
        # The handlers refer to the parser and the parser to them: break the cycle, or the
        # tree lives on until the cyclic collector happens to run.
        parser.StartElementHandler = parser.EndElementHandler = None
        parser.CharacterDataHandler = None
    return document.children[0]


_REFERENCES = re.compile(r"<!--.*?-->|<!\[CDATA\[.*?\]\]>|<\?.*?\?>|&([^#;\s<>&]+);", re.S)
_PREDEFINED = frozenset({"lt", "gt", "amp", "quot", "apos"})


def find_entity_references(text: str) -> tuple[EntityReference, ...]:
    """R-XML-11: references that a parser, having named but not read a DTD, drops in silence."""
    found = []
    line, line_start, counted = 1, 0, 0  # positions advance with the matches: one pass in all
    for match in _REFERENCES.finditer(text):
        name = match.group(1)
        if name is not None and name not in _PREDEFINED:
            offset = match.start()
            line += text.count("\n", counted, offset)
            line_start = max(line_start, text.rfind("\n", counted, offset) + 1)
            counted = offset
            found.append(EntityReference(name, line, offset - line_start + 1))
    return tuple(found)


def _unknown_encoding(data: bytes) -> ParseFailure:
    """D-XML-2: libxml2's own refusal, or ours where libxml2 knows an encoding Python does not."""
    from rcmlconf.markup.wellformed import libxml2_failure

    return libxml2_failure(data) or ParseFailure(
        "R-XML-1",
        1,
        1,
        "the declared encoding is not one rcmlconf can read",
        "use UTF-8 (D-XML-2)",
    )


def _syntax_failure(data: bytes, exc: expat.ExpatError) -> ParseFailure:
    """libxml2's first fatal error, or expat's own where libxml2 finds none."""
    from rcmlconf.markup.wellformed import libxml2_failure  # lxml only for broken documents

    return libxml2_failure(data) or ParseFailure(
        "R-XML-1", exc.lineno, exc.offset + 1, expat.ErrorString(exc.code) or str(exc)
    )
