"""Small helpers for messages people read."""

from __future__ import annotations

import pytest

from rcmlconf.wording import plural


@pytest.mark.parametrize(
    ("count", "text"),
    [(0, "0 frames"), (1, "1 frame"), (2, "2 frames"), (12345, "12,345 frames")],
)
def test_plural_says_one_thing_singular_and_groups_thousands(count: int, text: str) -> None:
    assert plural(count, "frame") == text
