"""`rcmlconf validate` as a library: check RCML, RXID and robot model documents, collect located
diagnostics."""

from rcmlconf.validate.validator import FileReport, Validator

__all__ = ["FileReport", "Validator"]
