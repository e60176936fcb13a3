"""Lexical forms of attribute values shared by the languages: names, enumerations, URIs, integers.

Each form is a function from the attribute's text to its value that raises `ValueTextError` with
a message a person can act on. Element tables (`markup.structure.Attr`) name these functions.
"""

from __future__ import annotations

import difflib
import re
from collections.abc import Callable, Iterable
from functools import cache, lru_cache

from rcmlconf.errors import ValueTextError

# XML 1.0 (fifth edition) productions [4], [4a], [5]; NCName is Name without ':'. The full
# classes take about 10 ms each to compile, so they are compiled on the first name that is not
# plain ASCII (which the small patterns decide alone).
_NAME_START = (
    "A-Z_a-z\u00c0-\u00d6\u00d8-\u00f6\u00f8-\u02ff\u0370-\u037d\u037f-\u1fff\u200c-\u200d"
    "\u2070-\u218f\u2c00-\u2fef\u3001-\ud7ff\uf900-\ufdcf\ufdf0-\ufffd\U00010000-\U000effff"
)
_NAME_MORE = r"\-.0-9\u00b7\u0300-\u036f\u203f-\u2040"
#: The XML `Name` production restricted to ASCII, for use in larger patterns.
ASCII_NAME_PATTERN = r"[:A-Z_a-z][-.0-9:A-Z_a-z]*"
_ASCII_NAME = re.compile(ASCII_NAME_PATTERN)
_ASCII_NCNAME = re.compile(r"[A-Z_a-z][-.0-9A-Z_a-z]*")


@cache
def _unicode(pattern: str) -> re.Pattern[str]:
    return re.compile(pattern)


def _is_name(text: str, ascii_pattern: re.Pattern[str], full: str) -> bool:
    if ascii_pattern.fullmatch(text) is not None:
        return True
    return not text.isascii() and _unicode(full).fullmatch(text) is not None


# A URI (or IRI) reference has no white space, no control character (C0, DEL, C1) and none of
# the characters RFC 3986 never allows; Unicode white space is excluded too (RFC 3987 ucschar).
URI_CHARACTERS = (
    r"[^\x00-\x20\x7f-\xa0<>\"{}|\\^`\u1680\u2000-\u200a\u2028\u2029\u202f\u205f\u3000\ufeff]"
)
_URI_REFERENCE = re.compile(f"{URI_CHARACTERS}+")
_ABSOLUTE_URI = re.compile(f"[A-Za-z][A-Za-z0-9+.-]*:{URI_CHARACTERS}+")
_UNSIGNED = re.compile(r"\+?[0-9]+")

TextParser = Callable[[str], object]


def is_name(text: str) -> bool:
    return _is_name(text, _ASCII_NAME, f"[:{_NAME_START}][:{_NAME_START}{_NAME_MORE}]*")


def xml_name(text: str) -> str:
    if not is_name(text):
        raise ValueTextError(
            f"{text!r} is not an XML Name (a letter, '_' or ':' first, then letters, digits, "
            "'.', '-', '_' or ':')"
        )
    return text


def ncname(text: str) -> str:
    if not _is_name(text, _ASCII_NCNAME, f"[{_NAME_START}][{_NAME_START}{_NAME_MORE}]*"):
        raise ValueTextError(f"{text!r} is not an XML NCName (a Name without ':')")
    return text


def uri_reference(text: str) -> str:
    if _URI_REFERENCE.fullmatch(text) is None:
        raise ValueTextError(
            f"{text!r} is not a URI reference (no white space or control characters)"
        )
    return text


def absolute_uri(text: str) -> str:
    if _ABSOLUTE_URI.fullmatch(text) is None:
        raise ValueTextError(f"{text!r} is not an absolute URI such as mailto:name@example.org")
    return text


def unsigned(low: int, high: int) -> TextParser:
    """An integer from `low` to `high` in decimal, with an optional '+'."""

    def parse(text: str) -> int:
        # Bound the digits first: int() refuses more than 4,300 digits with a ValueError.
        digits = text.lstrip("+").lstrip("0")
        if _UNSIGNED.fullmatch(text) is None:
            raise ValueTextError(f"{text!r} is not a whole number from {low} to {high}")
        if len(digits) > len(str(high)) or not low <= int(digits or "0") <= high:
            raise ValueTextError(f"{text} is not between {low} and {high}")
        return int(digits or "0")

    return parse


class Enumeration:
    """The lexical form "one of these texts, exactly as written", which says what they are."""

    def __init__(self, *choices: str) -> None:
        self.choices = choices
        self._allowed = frozenset(choices)

    def __call__(self, text: str) -> str:
        if text not in self._allowed:
            if len(self.choices) == 1:
                raise ValueTextError(f"must be {self.choices[0]!r}, not {text!r}")
            listing = ", ".join(self.choices)
            raise ValueTextError(
                f"{text!r} is not one of {listing}{did_you_mean(text, self.choices)}"
            )
        return text


def enumeration(*choices: str) -> Enumeration:
    """One of `choices`, exactly as written."""
    return Enumeration(*choices)


BOOLEAN = enumeration("true", "false")


def closest(word: str, choices: Iterable[str]) -> str | None:
    """The near miss among `choices` that `word` was probably meant to be.

    Cached, and not tried for words far longer than any choice: a hostile document may misspell
    a hundred thousand names, or one name a million characters long.
    """
    options = tuple(choices)
    if len(word) > 2 * max(map(len, options), default=0) + 8:
        return None
    return _closest(word, options)


@lru_cache(maxsize=1024)
def _closest(word: str, options: tuple[str, ...]) -> str | None:
    close = difflib.get_close_matches(word, options, n=1, cutoff=0.7)
    return close[0] if close else None


def did_you_mean(word: str, choices: Iterable[str]) -> str:
    """' (did you mean X?)' for a near miss among `choices`, else ''."""
    close = closest(word, choices)
    return f" (did you mean {close!r}?)" if close else ""
