"""The first fatal well-formedness error, as libxml2 reports it, with a hint where one helps.

Imported only when a document is not well-formed, so that valid documents never load lxml.
"""

from __future__ import annotations

import re
from collections.abc import Callable

from lxml import etree

from rcmlconf.markup.failure import MAX_DEPTH, ParseFailure

#: A hint from (libxml2 message, the document's line holding the error, 1-based column).
Hint = Callable[[str, str, int], str | None]


def libxml2_failure(data: bytes) -> ParseFailure | None:
    """None when libxml2 finds the document well-formed."""
    parser = etree.XMLParser(
        resolve_entities=False,
        no_network=True,
        load_dtd=False,
        huge_tree=False,
        collect_ids=False,
    )
    try:
        etree.fromstring(data, parser)
    except etree.XMLSyntaxError as exc:
        entry = next((e for e in parser.error_log if e.level >= etree.ErrorLevels.ERROR), None)
        if entry is None:
            line, column = exc.position
            return ParseFailure("R-XML-1", line or 1, (column or 0) + 1, str(exc.msg))
        if entry.type_name == "ERR_RESOURCE_LIMIT" and "depth" in entry.message:
            return ParseFailure(
                "R-XML-6", entry.line, entry.column, f"elements nest deeper than {MAX_DEPTH} levels"
            )
        message = entry.message.strip()
        hint = _HINTS.get(entry.type_name)
        here = _line(data, entry.line)
        return ParseFailure(
            "R-XML-1",
            entry.line,
            entry.column,
            message,
            hint(message, here, entry.column) if hint else None,
        )
    return None


def _line(data: bytes, number: int) -> str:
    lines = data.split(b"\n", number)
    return lines[number - 1].decode("utf-8", "replace") if len(lines) >= number else ""


def _space_required(message: str, line: str, column: int) -> str | None:
    if message != "attributes construct error":
        return None
    if 1 < column <= len(line) + 1 and line[column - 2] in "\"'":
        return "missing whitespace between attributes"
    return "a start tag ends with '>' or '/>', and attributes are name=\"value\""


_MISMATCH = re.compile(r"Opening and ending tag mismatch: (\S+) line (\d+) and (\S+)")


def _tag_mismatch(message: str, line: str, column: int) -> str | None:
    match = _MISMATCH.search(message)
    if match is None:
        return None
    opened, opened_line, _ = match.groups()
    return (
        f"<{opened}> opened on line {opened_line} is not closed; close it with </{opened}>, "
        "or end an empty element with '/>'"
    )


def _name_required(message: str, line: str, column: int) -> str | None:
    if "EntityRef" in message:
        return "write &amp; for a literal '&'"
    return "names start with a letter, '_' or ':'"


def _fixed(hint: str) -> Hint:
    return lambda message, line, column: hint


_HINTS: dict[str, Hint] = {
    "ERR_SPACE_REQUIRED": _space_required,
    "ERR_TAG_NAME_MISMATCH": _tag_mismatch,
    "ERR_NAME_REQUIRED": _name_required,
    "ERR_ATTRIBUTE_NOT_STARTED": _fixed('attribute values are quoted: name="value"'),
    "ERR_ATTRIBUTE_WITHOUT_VALUE": _fixed('every attribute has a value: name="value"'),
    "ERR_ATTRIBUTE_REDEFINED": _fixed("an attribute may appear once per element"),
    "ERR_TAG_NOT_FINISHED": _fixed("the document ends before this element is closed"),
    "ERR_LT_IN_ATTRIBUTE": _fixed("write &lt; for a literal '<'"),
    "ERR_UNDECLARED_ENTITY": _fixed(
        "only &lt; &gt; &amp; &quot; &apos; and character references (&#38;) are allowed"
    ),
    "ERR_DOCUMENT_END": _fixed("a document has exactly one root element"),
    "ERR_DOCUMENT_EMPTY": _fixed("the file holds no XML element"),
    "ERR_INVALID_ENCODING": _fixed(
        "the bytes do not match the declared encoding (UTF-8 unless the XML declaration says "
        "otherwise)"
    ),
    "NS_ERR_UNDEFINED_NAMESPACE": _fixed('declare the prefix with xmlns:prefix="URI"'),
}
