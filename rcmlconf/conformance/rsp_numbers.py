"""The numbers of specs/rsp.md the RSP cases and probes judge by, stated here rather than read from
the reference's constants (`rcmlconf/rsp/session/`): a robot or local system built from a changed
constant must not move the expectation with it (mutation testing found cases that did, issue 16)."""

#: D-RSP-12: a HELLO that gets no answer is repeated every 250 ms, five times at most.
HELLO_INTERVAL = 0.25
HELLO_RETRIES = 5
#: D-RSP-13: a side with nothing to say sends an empty Device Map every 5 periods; silence from
#: its peer for 25 periods means the link is lost; after 10 s the session ends with BYE.
KEEPALIVE_PERIODS = 5
LOST_PERIODS = 25
SESSION_TIMEOUT = 10.0
