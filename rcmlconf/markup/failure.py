"""What a document that cannot be read at all gives, and the bounds past which none is read.

Apart from `document` (the expat parse) so that `wellformed` (libxml2's account of a broken
document, imported only then) can give the same finding without importing the parser back.
"""

from __future__ import annotations

from dataclasses import dataclass

#: D-XML-5.
MAX_DOCUMENT_BYTES = 16 * 1024 * 1024
MAX_DEPTH = 256


@dataclass(frozen=True, slots=True)
class ParseFailure:
    """Why a document could not be read at all: one located finding."""

    rule: str
    line: int
    column: int
    message: str
    hint: str | None = None
