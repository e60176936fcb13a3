"""The element table of RCML 2.0 (specs/rcml-2.0.md §1): attributes, lexical forms and rules."""

from __future__ import annotations

from rcmlconf.markup.lexical import enumeration, unsigned, uri_reference, xml_name
from rcmlconf.markup.structure import Attr, ElementDef
from rcmlconf.rcml.model import PERMISSION_TEXTS, AccessType
from rcmlconf.rcml.url import parse_rctp_url
from rcmlconf.values import ALIASES, DATA_TYPES, parse_positive
from rcmlconf.values.types import MAX_COUNT, MAX_SIZE

PLACEMENT = "R-RCML-6"
NAME = Attr("R-RCML-7", xml_name, required=True)
PERMISSION = Attr("R-RCML-15", enumeration(*PERMISSION_TEXTS))
SECONDS = Attr("R-RCML-11", parse_positive)
TYPE_NAMES = (*DATA_TYPES, *ALIASES)

_NODE_CHILDREN = frozenset({"group", "access", "link", "meta"})

ELEMENTS: dict[str, ElementDef] = {
    "rcml": ElementDef(
        {
            "version": Attr("R-RCML-1", enumeration("2.0"), required=True),
            "site": Attr("R-RCML-2", parse_rctp_url, required=True),
            # timeSource and contact are SHOULDs: the loader warns about them itself.
            "timeSource": Attr(),
            "timePrecision": Attr("R-RCML-4", parse_positive),
            "title": Attr(),
            "author": Attr(),
            "info": Attr(),
            "contact": Attr(),
        },
        _NODE_CHILDREN,
        PLACEMENT,
    ),
    "group": ElementDef({"name": NAME, "permission": PERMISSION}, _NODE_CHILDREN, PLACEMENT),
    "access": ElementDef(
        {
            "name": NAME,
            "type": Attr("R-RCML-10", enumeration(*(t.value for t in AccessType))),
            "permission": PERMISSION,
            "readInterval": SECONDS,
            "writeInterval": SECONDS,
            "readTimeout": SECONDS,
            "writeTimeout": SECONDS,
        },
        frozenset({"data", "link", "meta"}),
        PLACEMENT,
    ),
    "data": ElementDef(
        {
            "name": NAME,
            "type": Attr("R-RCML-17", enumeration(*TYPE_NAMES), required=True),
            "permission": PERMISSION,
            "count": Attr("R-RCML-19", unsigned(1, MAX_COUNT)),
            "size": Attr("R-RCML-18", unsigned(1, MAX_SIZE)),
            # Their form depends on the node's type: the loader parses them (R-RCML-20).
            "min": Attr(),
            "max": Attr(),
        },
        frozenset({"link", "meta"}),
        PLACEMENT,
    ),
    "link": ElementDef(
        {
            "kind": Attr("R-RCML-25", required=True),
            "href": Attr("R-RCML-25", uri_reference, required=True),
            "title": Attr(),
        },
        placement_rule=PLACEMENT,
    ),
    "meta": ElementDef(
        {"name": Attr("R-RCML-28", required=True), "content": Attr("R-RCML-28", required=True)},
        placement_rule=PLACEMENT,
    ),
}
