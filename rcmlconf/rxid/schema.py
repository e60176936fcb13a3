"""The element table of RXID 2.0 (specs/rxid-2.0.md §1), derived from the widget table."""

from __future__ import annotations

from collections.abc import Mapping

from rcmlconf.markup.lexical import BOOLEAN, enumeration, ncname, unsigned, uri_reference, xml_name
from rcmlconf.markup.structure import Attr, ElementDef
from rcmlconf.rcml.paths import parse_node_path, parse_tree_path
from rcmlconf.rxid.widgets import ACTIONS, WIDGETS
from rcmlconf.values import parse_positive

PLACEMENT = "R-RXID-2"
MAX_COORDINATE = 2**31 - 1

_GEOMETRY = {
    "id": Attr("R-RXID-22", ncname),
    **{
        name: Attr("R-RXID-18", unsigned(0, MAX_COORDINATE))
        for name in ("x", "y", "width", "height")
    },
}
_SESSION = {"session": Attr("R-RXID-7", xml_name)}
_LINK = {
    "dataPath": Attr("R-RXID-8", parse_node_path, required=True, missing_rule="R-RXID-15"),
    **_SESSION,
}
_READ_ONLY = {"readOnly": Attr("R-RXID-23", BOOLEAN)}
_CAPTION = {"caption": Attr()}
_RANGE = {
    # min and max are values of the linked node's type: the loader parses them (R-RXID-17).
    "min": Attr(),
    "max": Attr(),
    "step": Attr("R-RXID-19", parse_positive),
    "orientation": Attr("R-RXID-23", enumeration("horizontal", "vertical")),
}

_WIDGET_ATTRIBUTES: dict[str, Mapping[str, Attr]] = {
    "box": _CAPTION,
    "label": {"caption": Attr("R-RXID-27", required=True)},
    "text": _LINK,
    "button": {
        **_CAPTION,
        **_LINK,
        "value": Attr("R-RXID-27", required=True),
        "releaseValue": Attr(),
    },
    "checkbox": {**_CAPTION, **_LINK, **_READ_ONLY, "onValue": Attr(), "offValue": Attr()},
    "radioGroup": {**_CAPTION, **_LINK, **_READ_ONLY},
    "scroll": {**_LINK, **_READ_ONLY, **_RANGE},
    "slider": {**_LINK, **_READ_ONLY, **_RANGE},
    "edit": {**_LINK, **_READ_ONLY},
    "popUpMenu": {**_LINK, **_READ_ONLY},
    "netmeeting": {"href": Attr("R-RXID-28", uri_reference)},
    "html": {"href": Attr("R-RXID-28", uri_reference, required=True, missing_rule="R-RXID-27")},
    "actionButton": {
        **_CAPTION,
        **_SESSION,
        "action": Attr("R-RXID-23", enumeration(*ACTIONS), required=True, missing_rule="R-RXID-27"),
        "target": Attr("R-RXID-8", parse_tree_path),
    },
}

# Known attributes a widget must not have, with the rule and the reason.
_STATIC = ("R-RXID-14", "it neither reads nor writes data (D-RXID-1)")
_NOT_BOTH = ("R-XML-8", "readOnly is for widgets that both read and write (D-RXID-5)")


def _forbidden(name: str) -> dict[str, tuple[str, str]]:
    widget = WIDGETS[name]
    own = _WIDGET_ATTRIBUTES[name]
    if not widget.linked:
        return {a: _STATIC for a in ("dataPath", "session", "readOnly") if a not in own}
    return {} if "readOnly" in own else {"readOnly": _NOT_BOTH}


_ITEM_HOLDERS = frozenset({"item"})

ELEMENTS: dict[str, ElementDef] = {
    "rxid": ElementDef(
        {"version": Attr("R-RXID-1", enumeration("2.0"), required=True), "title": Attr()},
        frozenset({"window"}),
        PLACEMENT,
    ),
    "window": ElementDef(
        {**_GEOMETRY, "title": Attr(), "background": Attr("R-RXID-28", uri_reference)},
        frozenset({"session", "access", *WIDGETS}),
        PLACEMENT,
    ),
    "session": ElementDef(
        {
            "name": Attr("R-RXID-6", xml_name),
            "href": Attr("R-RXID-5", uri_reference, required=True),
        },
        placement_rule=PLACEMENT,
    ),
    "access": ElementDef(
        {
            "dataPath": Attr("R-RXID-8", parse_node_path, required=True, missing_rule="R-RXID-27"),
            **_SESSION,
            "readInterval": Attr("R-RXID-25", parse_positive),
            "writeInterval": Attr("R-RXID-25", parse_positive),
            "autoStart": Attr("R-RXID-23", BOOLEAN),
        },
        placement_rule=PLACEMENT,
    ),
    "item": ElementDef(
        {"caption": Attr("R-RXID-27", required=True), "value": Attr("R-RXID-27", required=True)},
        placement_rule=PLACEMENT,
    ),
    **{
        name: ElementDef(
            {**_GEOMETRY, **_WIDGET_ATTRIBUTES[name]},
            _ITEM_HOLDERS if widget.items else frozenset(),
            PLACEMENT,
            _forbidden(name),
        )
        for name, widget in WIDGETS.items()
    },
}
