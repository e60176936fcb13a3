"""rcmlconf: conformance suite and protocol analyser for RCML 2.0, RXID 2.0, RCTP/2.0 and RSP."""

__version__ = "0.1.0"
