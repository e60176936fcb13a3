"""The element table of the robot model (specs/rsp.md §1, D-RSP-1): attributes, forms and rules."""

from __future__ import annotations

from dataclasses import replace

from rcmlconf.errors import ValueTextError
from rcmlconf.markup.lexical import enumeration, unsigned, xml_name
from rcmlconf.markup.structure import Attr, ElementDef
from rcmlconf.rcml.schema import ELEMENTS as RCML_ELEMENTS
from rcmlconf.rsp.model import (
    ID_LENGTHS,
    MAX_COMMAND_BUFFERS,
    MAX_MODEL_ID,
    MAX_PERIOD,
    MIN_PERIOD,
    DeviceKind,
    OnLoss,
)
from rcmlconf.values import parse_positive

PLACEMENT = "R-RSP-4"
#: R-RSP-5: devices and fields.
NAME = Attr("R-RSP-5", xml_name, required=True)


def parse_period(text: str) -> float:
    """A period T: D-RCML-7's positive number of seconds, from 5 ms to 10 s (D-RSP-13)."""
    seconds = parse_positive(text)
    if not MIN_PERIOD <= seconds <= MAX_PERIOD:
        raise ValueTextError(f"{text} s is not from {MIN_PERIOD:g} to {MAX_PERIOD:g} seconds")
    return seconds


def _as_field(attr: Attr) -> Attr:
    """A data node's attribute as a field's: the same form, under R-RSP-8 (D-RSP-4)."""
    return replace(attr, rule="R-RSP-8") if attr.rule else attr


_DATA = RCML_ELEMENTS["data"].attributes
DEVICES = frozenset(kind.value for kind in DeviceKind)
#: The kinds that declare fields of their own (R-RSP-7).
FIELD_HOLDERS = frozenset(kind.value for kind in DeviceKind if kind.has_fields)
_META = frozenset({"meta"})
_PAYLOAD = frozenset({"field", "meta"})

ELEMENTS: dict[str, ElementDef] = {
    "robotModel": ElementDef(
        {
            "version": Attr("R-RSP-1", enumeration("1"), required=True),
            "name": Attr("R-RSP-2", required=True),
            "modelId": Attr("R-RSP-2", unsigned(1, MAX_MODEL_ID), required=True),
            "idLength": Attr("R-RSP-3", enumeration(*map(str, ID_LENGTHS))),
            "commandBuffers": Attr("R-RSP-3", unsigned(1, MAX_COMMAND_BUFFERS)),
            "period": Attr("R-RSP-3", parse_period),
            "title": Attr(),
            "author": Attr(),
        },
        DEVICES | _META,
        PLACEMENT,
    ),
    # D-RSP-3: modules do not nest.
    "module": ElementDef({"name": NAME}, DEVICES - {"module"} | _META, PLACEMENT),
    "effector": ElementDef(
        {"name": NAME, "onLoss": Attr("R-RSP-3", enumeration(*(o.value for o in OnLoss)))},
        _PAYLOAD,
        PLACEMENT,
    ),
    **{
        name: ElementDef({"name": NAME}, _PAYLOAD, PLACEMENT)
        for name in sorted(FIELD_HOLDERS - {"effector"})
    },
    # D-RSP-4: a monitor's fields are its effector's; `of` names it.
    "monitor": ElementDef({"name": NAME, "of": Attr("R-RSP-9", required=True)}, _META, PLACEMENT),
    "field": ElementDef(
        {
            "name": NAME,
            **{name: _as_field(_DATA[name]) for name in ("type", "count", "size", "min", "max")},
            "unit": Attr(),
        },
        _META,
        PLACEMENT,
    ),
    # specs/rsp.md has no rule of its own for meta's name and content: they are RCML's (R-RCML-28).
    "meta": ElementDef(RCML_ELEMENTS["meta"].attributes, placement_rule=PLACEMENT),
}
