"""Decode a document's bytes the way an XML parser will (D-XML-2).

The text is screened (prolog, entity references) and, re-encoded as UTF-8, fed to expat.
"""

from __future__ import annotations

import codecs
import re

_DECLARED = re.compile(rb"<\?xml[^>]*?encoding\s*=\s*[\"']([A-Za-z][A-Za-z0-9._-]*)[\"']")

_BOMS = (
    (codecs.BOM_UTF8, "utf-8-sig"),
    (codecs.BOM_UTF16_LE, "utf-16-le"),
    (codecs.BOM_UTF16_BE, "utf-16-be"),
    (b"<\x00?\x00", "utf-16-le"),
    (b"\x00<\x00?", "utf-16-be"),
)


def python_codec(data: bytes) -> str | None:
    """The Python codec matching the document's byte order mark or XML declaration.

    None when the declared encoding is one Python does not know (D-XML-2).
    """
    for prefix, name in _BOMS:
        if data.startswith(prefix):
            return name
    match = _DECLARED.match(data, 0, 256)
    if match is None:
        return "utf-8"
    try:
        return codecs.lookup(match.group(1).decode("ascii")).name
    except LookupError:
        return None


def decode_document(data: bytes, codec: str) -> str:
    """The document as text, without a byte order mark; undecodable bytes become U+FFFD."""
    text = data.decode(codec, errors="replace")
    return text[1:] if text.startswith("\ufeff") else text
