"""Small helpers for messages people read."""

from collections.abc import Sequence


def shorten(text: str, limit: int = 40) -> str:
    """Text a document supplied, cut to fit in a one-line message."""
    return text if len(text) <= limit else text[: limit - 3] + "..."


def one_line(text: str) -> str:
    """`text` as one printable line: the bytes of a name that were not UTF-8 as U+FFFD, as click
    shows them, and any other character that is not printable escaped (a newline as \\n)."""
    try:
        text = text.encode("utf-8", "surrogateescape").decode("utf-8", "replace")
    except UnicodeEncodeError:
        text = text.encode("utf-8", "replace").decode("utf-8")
    if text.isprintable():
        return text
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in text)


def quoted(text: str, limit: int = 80) -> str:
    """A value the user gave, quoted in a message: shortened, on one printable line."""
    return f"'{one_line(shorten(text, limit))}'"


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
