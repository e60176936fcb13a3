"""Screen a document's prolog before any XML parser sees it (D-XML-3, D-XML-4).

libxml2 expands internal entities in attribute values even with entity resolution off, so the
only safe treatment of an internal DTD subset is to refuse it unparsed. The prolog grammar
(XML declaration, comments, processing instructions, one DOCTYPE) is small enough to scan exactly.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

_NAME = re.compile(r"[^\s\[>\"']+")
_LITERAL = re.compile(r"\"[^\"]*\"|'[^']*'")


@dataclass(frozen=True, slots=True)
class Doctype:
    name: str
    system_id: str | None
    #: Where `<!DOCTYPE` starts (1-based).
    line: int
    column: int
    #: Character offset of the `[` opening an internal subset, or None when there is none.
    subset_offset: int | None
    declares_entities: bool


def _skip_space(text: str, pos: int) -> int:
    end = len(text)
    while pos < end and text[pos] in " \t\r\n":
        pos += 1
    return pos


def screen_prolog(text: str) -> Doctype | None:
    """The document's DOCTYPE, if its prolog has one. Malformed prologs are left to libxml2."""
    pos = 0
    end = len(text)
    while pos < end:
        pos = _skip_space(text, pos)
        if text.startswith("<!--", pos):
            close = text.find("-->", pos + 4)
            if close < 0:
                return None
            pos = close + 3
        elif text.startswith("<?", pos):
            close = text.find("?>", pos + 2)
            if close < 0:
                return None
            pos = close + 2
        elif text.startswith("<!DOCTYPE", pos):
            return _doctype(text, pos)
        else:
            return None
    return None


def _doctype(text: str, start: int) -> Doctype | None:
    pos = _skip_space(text, start + 9)
    name_match = _NAME.match(text, pos)
    if name_match is None:
        return None
    pos = name_match.end()
    literals: list[str] = []
    while True:
        pos = _skip_space(text, pos)
        keyword = _NAME.match(text, pos)
        literal = _LITERAL.match(text, pos)
        if literal is not None:
            literals.append(literal.group()[1:-1])
            pos = literal.end()
        elif keyword is not None and keyword.group() in ("SYSTEM", "PUBLIC"):
            pos = keyword.end()
        else:
            break
    subset = pos if text.startswith("[", pos) else None
    declares = False
    if subset is not None:
        close = text.find("]>", subset)
        declares = "<!ENTITY" in text[subset : close if close >= 0 else len(text)]
    # SYSTEM "x" gives one literal; PUBLIC "pub" "x" gives two, the system identifier last.
    line, column = text_position(text, start)
    return Doctype(
        name_match.group(), literals[-1] if literals else None, line, column, subset, declares
    )


def text_position(text: str, offset: int) -> tuple[int, int]:
    """1-based line and column of a character offset."""
    line_start = text.rfind("\n", 0, offset) + 1
    return text.count("\n", 0, offset) + 1, offset - line_start + 1
