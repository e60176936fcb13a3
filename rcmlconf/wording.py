"""Small helpers for messages people read."""


def shorten(text: str, limit: int = 40) -> str:
    """Text a document supplied, cut to fit in a one-line message."""
    return text if len(text) <= limit else text[: limit - 3] + "..."


def plural(count: int, noun: str) -> str:
    """`1 error`, `2 errors`."""
    return f"{count} {noun}{'' if count == 1 else 's'}"
