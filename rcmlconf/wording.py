"""Small helpers for messages people read."""

from collections.abc import Sequence


def shorten(text: str, limit: int = 40) -> str:
    """Text a document supplied, cut to fit in a one-line message."""
    return text if len(text) <= limit else text[: limit - 3] + "..."


def plural(count: int, noun: str) -> str:
    """`1 error`, `2 errors`, `12,345 frames`."""
    return f"{count:,} {noun}{'' if count == 1 else 's'}"


def indefinite(noun: str) -> str:
    """`an effector`, `a sensor`, `an ACK`: the article by the word's first letter, which is
    right for the words rcmlconf puts one before (device kinds, packet types)."""
    return f"{'an' if noun[:1].lower() in 'aeiou' else 'a'} {noun}"


def one_of(words: Sequence[str]) -> str:
    """`a`, `a or b`, `a, b or c`."""
    return " or ".join(filter(None, (", ".join(words[:-1]), words[-1]))) if words else ""
