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
#: D-RSP-17's retransmission timeout: 10 T before the first round trip is measured, at least
#: 2 T, at most 2 s (the ceiling wins), doubled after each retransmission.
INITIAL_RTO_PERIODS = 10
MIN_RTO_PERIODS = 2
MAX_RTO = 2.0


def unmeasured_rto(period: float, retransmissions: int) -> float:
    """D-RSP-17's timeout before any round trip is measured, after `retransmissions` (seconds)."""
    rto = min(max(INITIAL_RTO_PERIODS * period, MIN_RTO_PERIODS * period), MAX_RTO)
    for _ in range(retransmissions):
        rto = min(2 * rto, MAX_RTO)
    return rto
