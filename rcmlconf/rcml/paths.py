"""Node paths (D-RCML-3): `/` and XML Names separated by `/`; `/` alone is the whole tree."""

from __future__ import annotations

from rcmlconf.errors import ValueTextError
from rcmlconf.markup.lexical import is_name


def parse_node_path(text: str) -> str:
    """A path naming a node (never the bare `/`)."""
    if text == "/":
        raise ValueTextError("'/' is the whole tree, not a node")
    return parse_tree_path(text)


def parse_tree_path(text: str) -> str:
    """A path naming a node, or `/` for the whole tree."""
    if not text.startswith("/"):
        raise ValueTextError(f"{text!r} does not start with '/': paths are absolute")
    if text == "/":
        return text
    for segment in text[1:].split("/"):
        if not segment:
            raise ValueTextError(f"{text!r} has an empty segment (a doubled or trailing '/')")
        if not is_name(segment):
            raise ValueTextError(f"segment {segment!r} of {text!r} is not an XML Name")
    return text


def is_within(path: str, top: str) -> bool:
    """Whether `path` is `top` or a node below it (`/` holds everything)."""
    return top == "/" or path == top or path.startswith(top + "/")
