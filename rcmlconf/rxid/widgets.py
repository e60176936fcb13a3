"""The thirteen widgets of the paper's Table 4: R/W columns (D-RXID-1) and types (D-RXID-6)."""

from __future__ import annotations

from dataclasses import dataclass

from rcmlconf.values import Kind

_SCALARS = frozenset(Kind)
_NUMBERS = frozenset({Kind.INTEGER, Kind.FLOAT})


@dataclass(frozen=True, slots=True)
class Widget:
    name: str
    #: The R column: the widget shows the linked node's value.
    reads: bool
    #: The W column: the widget writes the user's input to the linked node.
    writes: bool
    #: Kinds of data node it may link to (D-RXID-6); empty for widgets that take no dataPath.
    kinds: frozenset[Kind] = frozenset()
    #: Whether it may link to an array node (count > 1).
    arrays: bool = False
    #: Whether it holds `item` children.
    items: bool = False
    #: Whether it runs over a range from `min` to `max` (scroll, slider).
    ranged: bool = False

    @property
    def linked(self) -> bool:
        return self.reads or self.writes


WIDGETS: dict[str, Widget] = {
    w.name: w
    for w in (
        Widget("box", reads=False, writes=False),
        Widget("label", reads=False, writes=False),
        Widget("text", reads=True, writes=False, kinds=_SCALARS, arrays=True),
        Widget("button", reads=False, writes=True, kinds=_SCALARS),
        Widget("checkbox", reads=True, writes=True, kinds=frozenset({Kind.BOOL, Kind.INTEGER})),
        Widget("radioGroup", reads=True, writes=True, kinds=_SCALARS, items=True),
        Widget("scroll", reads=True, writes=True, kinds=_NUMBERS, ranged=True),
        Widget("slider", reads=True, writes=True, kinds=_NUMBERS, ranged=True),
        Widget("edit", reads=True, writes=True, kinds=_SCALARS),
        Widget("popUpMenu", reads=True, writes=True, kinds=_SCALARS, items=True),
        Widget("netmeeting", reads=False, writes=False),
        Widget("html", reads=False, writes=False),
        Widget("actionButton", reads=False, writes=False),
    )
}

#: D-RXID-7: RCTP methods an actionButton may send, and whether they take a target.
ACTIONS = {
    "connect": False,
    "acquire": True,
    "release": True,
    "setup": True,
    "go": True,
    "pause": True,
    "stop": True,
    "bye": False,
}
