"""The numbers of specs/rsp.md the RSP cases and probes judge by, stated here rather than read from
the reference's constants (`rcmlconf/rsp/session/`): a robot or local system built from a changed
constant must not move the expectation with it (mutation testing found cases that did, issue 16)."""

#: D-RSP-12: a HELLO that gets no answer is repeated every 250 ms, five times at most.
HELLO_INTERVAL = 0.25
HELLO_RETRIES = 5
#: D-RSP-13: a harness judges each single gap of a pace within these fractions of its interval.
GAP_SHORTEST, GAP_LONGEST = 0.6, 1.6
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
#: R-RSP-31: a memory command taken while the robot executes none has left the buffer within
#: this many periods T.
START_PERIODS = 3


def unmeasured_rto(period: float, retransmissions: int) -> float:
    """D-RSP-17's timeout before any round trip is measured, after `retransmissions` (seconds)."""
    rto = min(max(INITIAL_RTO_PERIODS * period, MIN_RTO_PERIODS * period), MAX_RTO)
    for _ in range(retransmissions):
        rto = min(2 * rto, MAX_RTO)
    return rto


# D-RSP-26: how closely a side's clock and timers hold, as a harness on loopback judges them. Each
# slack (what a bound allows past the time the spec names) is multiplied by --timeout-scale.

#: A sender's clock runs within this fraction of the harness's.
CLOCK_DRIFT = 0.05
#: Seconds between a packet made and stamped and its arrival read, on a loaded machine.
STAMP_LAG = 0.05
#: Milliseconds a span between two stamps of one sender may fall short of a time it waited: each
#: stamp is a whole millisecond.
STAMP_ROUNDING = 2
#: Periods the median keep-alive gap may be off 5 T.
KEEPALIVE_SLACK = 0.5
#: Seconds past D-RSP-20's 27 periods within which a stop is seen.
STOP_LAG = 0.5
#: Seconds before and after the 10 s of the session timeout within which its BYE comes (where T
#: is a second or less).
TIMEOUT_EARLY, TIMEOUT_LATE = 0.5, 1.0


def stamp_allowance(span: float, scale: float) -> float:
    """Milliseconds a span of `span` seconds between two of a sender's timestamps may differ from
    the harness's clock (D-RSP-26)."""
    return (CLOCK_DRIFT * span + STAMP_LAG * scale) * 1000


#: Seconds for the wire and the scheduling of both sides, past a retransmission's next packet,
#: and past the two periods after a packet in which its receiver may still send what it made
#: before it had it (D-RSP-26).
RESEND_LAG = 0.1
#: Periods after a packet went in which its receiver may still send what it made before it had
#: it: one packet in flight as it went, one made as it arrived (D-RSP-26).
UNHEARD_PERIODS = 2


def unheard_for(period: float, scale: float) -> float:
    """Seconds after a packet went past which what its receiver sends was sent after it had it
    (D-RSP-26); a hold of the harness's loop excuses as much more."""
    return UNHEARD_PERIODS * period + RESEND_LAG * scale


def resent_within(rto: float, period: float, scale: float) -> float:
    """Seconds after the send before within which a retransmission due after `rto` is seen: the
    timeout and a quarter for the timer, a period for the next packet, RESEND_LAG (D-RSP-26)."""
    return rto + period + (0.25 * rto + RESEND_LAG) * scale


def measured_rto(held: float, period: float) -> tuple[float, float]:
    """D-RSP-17's timeout after one round trip measured, 3 R within its bounds, R at least `held`
    (seconds the harness held its ACK, by a clock within CLOCK_DRIFT) and at most that and two
    periods (D-RSP-26): the shortest and the longest it may be."""

    def bounded(trip: float) -> float:
        return min(max(3 * trip, MIN_RTO_PERIODS * period), MAX_RTO)

    return bounded((1 - CLOCK_DRIFT) * held), bounded(held + 2 * period)


def timeout_window(period: float, scale: float) -> tuple[float, float]:
    """Seconds after the last packet a side heard within which its session timeout's BYE comes
    (D-RSP-26): up to 10 s and T where T is over a second."""
    return SESSION_TIMEOUT - TIMEOUT_EARLY, SESSION_TIMEOUT + max(TIMEOUT_LATE, period) * scale
