"""RCTP/2.0: the control connection and data stream of RCML 2.0 (specs/rctp-2.0.md, to come)."""
