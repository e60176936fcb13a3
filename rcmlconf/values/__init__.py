"""RCML data types and their two forms: binary (D-RCML-10, shared by RCTP and RSP) and text.

The binary codec lives in `rcmlconf.values.binary`; it is not imported here, because checking a
document never needs it.
"""

from rcmlconf.values.text import format_value_text, parse_positive, parse_value_text
from rcmlconf.values.types import (
    ALIASES,
    DATA_TYPES,
    DataType,
    Kind,
    Scalar,
    Value,
    ValueType,
    first_outside,
    lookup_type,
)

__all__ = [
    "ALIASES",
    "DATA_TYPES",
    "DataType",
    "Kind",
    "Scalar",
    "Value",
    "ValueType",
    "first_outside",
    "format_value_text",
    "lookup_type",
    "parse_positive",
    "parse_value_text",
]
