"""`rcmlconf validate` as a library: check RCML and RXID documents, collect located diagnostics."""

from rcmlconf.validate.validator import FileReport, Validator

__all__ = ["FileReport", "Validator"]
