"""The flawed encodings the value cases send (`rcmlconf.conformance.flaws`), made from the type
table of D-RCML-9 for every type: each malformed one is refused by the core's decoder, which
holds to R-RCML-30 and D-RCML-11, and each out-of-range one decodes to a value outside its range
(D-RCML-12); a holder gets exactly the flaws its declaration allows."""

from __future__ import annotations

import math

import pytest

from rcmlconf.conformance.flaws import Flaw, flawed
from rcmlconf.errors import ProtocolError
from rcmlconf.rsp.model import Field
from rcmlconf.values import DATA_TYPES, Kind, ValueType, first_outside
from rcmlconf.values.binary import decode_value
from rcmlconf.values.types import MAX_SIZE

#: Bounds of each kind of number, in its type's text form.
BOUNDS = {Kind.INTEGER: (-5, 100), Kind.FLOAT: (-1.5, 2.5)}


def holders() -> list[Field]:
    """Every type of the table, alone and as an array, with and without a range."""
    found = []
    for base in DATA_TYPES.values():
        size = 8 if base.sized else 0
        for count in (1, 3):
            vtype = ValueType(base, count, size)
            found.append(Field(f"{base.name}x{count}", vtype))
            if base.kind in BOUNDS:
                low, high = BOUNDS[base.kind]
                low = max(low, base.low) if base.kind is Kind.INTEGER else low
                found.append(Field(f"{base.name}x{count}-ranged", vtype, low, high))
    return found


def expected(field: Field) -> set[Flaw]:
    """The flaws D-RCML-9 to D-RCML-12 give a declaration."""
    kind, ranged = field.type.base.kind, field.minimum is not None
    flaws = {Flaw.ITEM_COUNT} if field.type.count > 1 else set()
    if kind is Kind.BOOL:
        flaws.add(Flaw.BOOL_BYTE)
    if kind in (Kind.STRING, Kind.BYTES):
        flaws |= {Flaw.OVER_SIZE, Flaw.PAST_END}
    if kind is Kind.STRING:
        flaws.add(Flaw.NOT_UTF8)
    if ranged:
        flaws.add(Flaw.OUT_OF_RANGE)
    if ranged and kind is Kind.FLOAT:
        flaws.add(Flaw.NAN)
    return flaws


@pytest.mark.parametrize("field", holders(), ids=lambda f: f.name)
def test_each_type_gets_the_flaws_its_declaration_allows(field: Field) -> None:
    assert {flaw for flaw in Flaw if flawed(field, flaw)} == expected(field)


@pytest.mark.parametrize("field", holders(), ids=lambda f: f.name)
def test_malformed_encodings_do_not_decode_and_the_others_leave_the_range(field: Field) -> None:
    for flaw in Flaw:
        for bad in flawed(field, flaw):
            if flaw.malformed:
                with pytest.raises(ProtocolError) as refused:
                    decode_value(field.type, bad.data)
                # A value cut short names no rule: the body it is cut from does (R-RCTP-28).
                assert refused.value.rule in ("R-RCML-30", None), bad.what
                continue
            value = decode_value(field.type, bad.data)
            index = first_outside(value, field.minimum, field.maximum)
            assert index == field.type.count - 1, bad.what  # the last item, the others valid
            if flaw is Flaw.NAN:  # NaN equals nothing, itself neither
                last = value[-1] if isinstance(value, tuple) else value
                assert isinstance(last, float), bad.what
                assert math.isnan(last), bad.what
            else:
                assert value == bad.lenient, bad.what


def test_a_lenient_reader_would_take_a_value_the_case_can_tell_apart() -> None:
    flag = Field("flag", ValueType(DATA_TYPES["bool"]))
    assert [b.lenient for b in flawed(flag, Flaw.BOOL_BYTE)] == [True, True]
    assert [b.data for b in flawed(flag, Flaw.BOOL_BYTE)] == [b"\x02", b"\xff"]
    text = Field("text", ValueType(DATA_TYPES["string"], 1, 4))
    (longer,) = flawed(text, Flaw.OVER_SIZE)
    assert (longer.data, longer.lenient) == (b"\x00\x05aaaaa", "aaaaa")
    (cut,) = flawed(text, Flaw.PAST_END)
    assert (cut.data, cut.lenient) == (b"\x00\x04aaa", "aaa")


def test_no_flaw_is_made_that_the_type_cannot_show() -> None:
    largest = Field("blob", ValueType(DATA_TYPES["bytes"], 1, MAX_SIZE))
    assert flawed(largest, Flaw.OVER_SIZE) == []  # no length above 65,535 exists
    full = Field("byte", ValueType(DATA_TYPES["uint8"]), 0, 255)
    assert flawed(full, Flaw.OUT_OF_RANGE) == []  # the range is the type's
    wide = Field("wide", ValueType(DATA_TYPES["float32"]), None, 3e38)
    found = [b.lenient for b in flawed(wide, Flaw.OUT_OF_RANGE)]
    assert found == [math.inf]  # past 3e38 a float32 holds only infinity
