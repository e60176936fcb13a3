"""The decimal text of the small numbers a record's line shows, made once, for the text and the JSON
lines alike."""

from __future__ import annotations

from functools import cache


@cache
def decimal_texts() -> tuple[str, ...]:
    """The decimal text of 0 to 65,535, the fields of 16 bits and fewer (sequence numbers,
    lengths, stream ids, ...): taken from here, a number of a line costs a fifth of writing it,
    and a line's numbers cost more than the rest of it. Made once, when the first `TextFormat`
    or `JsonFormat` is (4 MB, 10 ms)."""
    return tuple(map(str, range(1 << 16)))
