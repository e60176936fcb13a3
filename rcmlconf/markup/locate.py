"""Positions in a document's UTF-8 source: byte offsets to 1-based line and column.

Columns count characters, as libxml2's do (D-XML-2). Only documents with findings ask, so the
line index is built on the first question. All the positions of a document are found in one pass
over the offsets in order: a hostile document of one line 16 MiB long, with a finding at each of
a thousand elements near its end, must not decode that line a thousand times.
"""

from __future__ import annotations

import bisect
import re
from collections.abc import Sequence

# Possessive quantifiers: linear, and no backtracking state, even for a tag megabytes long.
_START_TAG = re.compile(rb"<[^\s/>]++(?:[^>\"']++|\"[^\"]*+\"|'[^']*+')*+>")
_ATTRIBUTE = re.compile(rb"([^\s=/>]++)\s*+=\s*+(?:\"[^\"]*+\"|'[^']*+')")


class SourceMap:
    def __init__(self, source: bytes) -> None:
        self.source = source
        self._line_starts: list[int] | None = None

    def position(self, offset: int) -> tuple[int, int]:
        return self.positions([offset])[0]

    def positions(self, offsets: Sequence[int]) -> list[tuple[int, int]]:
        """(line, column) of each offset; the offsets in ascending order."""
        if self._line_starts is None:
            self._line_starts = [0] + [m.end() for m in re.finditer(b"\n", self.source)]
        ascii_only = self.source.isascii()  # then a column is a difference of offsets
        found = []
        line = column = 0
        previous = -1
        for offset in offsets:
            here = bisect.bisect_right(self._line_starts, offset)
            if here != line:  # a new line: count from its start
                line, previous, column = here, self._line_starts[here - 1], 1
            if ascii_only:
                column += offset - previous
            else:
                column += len(self.source[previous:offset].decode("utf-8", "replace"))
            previous = offset
            found.append((line, column))
        return found

    def attribute_offset(self, tag_offset: int, name: str) -> int:
        """Offset of attribute `name` in the start tag at `tag_offset` (the tag's, if absent)."""
        tag = _START_TAG.match(self.source, tag_offset)
        if tag is not None:
            wanted = name.encode("utf-8")
            for match in _ATTRIBUTE.finditer(self.source, tag_offset, tag.end()):
                if match.group(1) == wanted:
                    return match.start()
        return tag_offset
