"""Positions in a document's UTF-8 source: byte offsets to 1-based line and column.

Columns count characters, as libxml2's do (D-XML-2). Only documents with findings ask, so the
line index is built on the first question.
"""

from __future__ import annotations

import bisect
import re

# Possessive quantifiers: linear, and no backtracking state, even for a tag megabytes long.
_START_TAG = re.compile(rb"<[^\s/>]++(?:[^>\"']++|\"[^\"]*+\"|'[^']*+')*+>")
_ATTRIBUTE = re.compile(rb"([^\s=/>]++)\s*+=\s*+(?:\"[^\"]*+\"|'[^']*+')")


class SourceMap:
    def __init__(self, source: bytes) -> None:
        self.source = source
        self._line_starts: list[int] | None = None

    def position(self, offset: int) -> tuple[int, int]:
        if self._line_starts is None:
            self._line_starts = [0] + [m.end() for m in re.finditer(b"\n", self.source)]
        line = bisect.bisect_right(self._line_starts, offset)
        start = self._line_starts[line - 1]
        column = len(self.source[start:offset].decode("utf-8", "replace")) + 1
        return line, column

    def attribute_offset(self, tag_offset: int, name: str) -> int:
        """Offset of attribute `name` in the start tag at `tag_offset` (the tag's, if absent)."""
        tag = _START_TAG.match(self.source, tag_offset)
        if tag is not None:
            wanted = name.encode("utf-8")
            for match in _ATTRIBUTE.finditer(self.source, tag_offset, tag.end()):
                if match.group(1) == wanted:
                    return match.start()
        return tag_offset
