"""RCTP/2.0, the protocol of RCML 2.0 (specs/rctp-2.0.md), as a sans-IO core.

The control connection: `connection.Connection` (either role; bytes and time in, events and bytes
out), built on `reader` and `writer` (messages, `messages`), `states` (the state machines as
tables), `request_checks` (what a request's receiver answers on its own, D-RCTP-25, which the
dissector asks too), `fields` and `targets` (header values, request-targets). The data stream:
`datastream` (packets, FLOW payloads, sequence order, clocks, DATA values). The `rctp://` URL
an RCML names its server by is RCML's (`rcml.url`, D-RCML-17).
"""
