"""One impaired direction in simulated time: statistics, bounds, order and determinism."""

from __future__ import annotations

import itertools

import pytest
from hypothesis import given
from hypothesis import strategies as st

from rcmlconf.impair.channel import (
    Counts,
    ImpairedChannel,
    channel_pair,
    derive_seed,
)
from rcmlconf.impair.spec import Impairment, parse_impairment

N = 20_000


def datagram(i: int) -> bytes:
    return i.to_bytes(4, "big") + b"payload"


def number(data: bytes) -> int:
    return int.from_bytes(data[:4], "big")


def simulate(
    channel: ImpairedChannel, sends: list[tuple[float, bytes]]
) -> list[tuple[float, bytes]]:
    """Send each datagram at its time and collect every delivery at exactly the channel's timer."""
    out: list[tuple[float, bytes]] = []
    pending = list(sends)
    pending.reverse()
    while pending or channel.get_timer() is not None:
        timer = channel.get_timer()
        if pending and (timer is None or pending[-1][0] <= timer):
            at, data = pending.pop()
            channel.send(data, at)
            out.extend((at, d) for d in channel.due(at))
        else:
            assert timer is not None
            out.extend((timer, d) for d in channel.due(timer))
    return out


def every(step: float, n: int = N) -> list[tuple[float, bytes]]:
    return [(i * step, datagram(i)) for i in range(n)]


def channel(spec: str, seed: int = 1, **kwargs: int) -> ImpairedChannel:
    return ImpairedChannel(parse_impairment(spec), seed, **kwargs)


def lost_numbers(chan: ImpairedChannel, n: int = N) -> list[int]:
    delivered = {number(d) for _, d in simulate(chan, every(0.001, n))}
    return [i for i in range(n) if i not in delivered]


def mean_run(lost: list[int]) -> float:
    runs = [len(list(g)) for _, g in itertools.groupby(enumerate(lost), lambda p: p[1] - p[0])]
    return sum(runs) / len(runs)


def test_no_impairment_is_the_identity_in_order_with_no_delay() -> None:
    chan = channel("none")
    for i in range(1000):
        now = i * 0.0007
        chan.send(datagram(i), now)
        assert chan.get_timer() == now
        assert chan.due(now) == [datagram(i)]
        assert chan.get_timer() is None
    assert chan.counts == Counts(sent=1000, delivered=1000)


def test_a_datagram_is_not_due_before_its_time() -> None:
    chan = channel("delay=40ms")
    chan.send(b"x", 10.0)
    assert chan.get_timer() == pytest.approx(10.04)
    assert chan.due(10.039) == []
    assert chan.held == 1
    assert chan.due(10.04) == [b"x"]
    assert chan.get_timer() is None


def test_the_same_seed_gives_the_same_deliveries_and_another_seed_others() -> None:
    spec = "loss=10%,burst=2,delay=20ms,jitter=5ms,reorder=5%,duplicate=5%,corrupt=5%"
    sends = every(0.002, 5000)
    first = simulate(channel(spec, seed=7), sends)
    assert simulate(channel(spec, seed=7), sends) == first
    assert simulate(channel(spec, seed=8), sends) != first


def test_the_fates_do_not_depend_on_the_other_settings() -> None:
    plain = lost_numbers(channel("loss=10%", seed=3), 5000)
    assert lost_numbers(channel("loss=10%,delay=40ms,jitter=10ms,gap=1ms", seed=3), 5000) == plain
    assert lost_numbers(channel("loss=10%,duplicate=20%,reorder=5%", seed=3), 5000) != []


def test_independent_loss_rate_and_runs() -> None:
    chan = channel("loss=5%")
    lost = lost_numbers(chan)
    assert chan.counts.lost == len(lost)
    assert 0.042 < len(lost) / N < 0.058  # 1000 expected, sigma 31
    assert 1.0 <= mean_run(lost) < 1.1  # 1/(1 - p) = 1.053


@pytest.mark.parametrize(("loss", "burst"), [(0.05, 3.0), (0.2, 5.0), (0.03, 1.5), (0.5, 1.0)])
def test_burst_loss_keeps_the_rate_and_has_the_mean_run_length(loss: float, burst: float) -> None:
    lost = lost_numbers(ImpairedChannel(Impairment(loss=loss, burst=burst), 11))
    assert len(lost) / N == pytest.approx(loss, rel=0.3)
    assert mean_run(lost) == pytest.approx(burst, rel=0.15)


def test_loss_of_everything_and_of_nothing() -> None:
    assert len(lost_numbers(channel("loss=100%"), 1000)) == 1000
    assert len(lost_numbers(channel("loss=100%,burst=3"), 1000)) == 1000
    assert lost_numbers(channel("burst=3"), 1000) == []


def test_duplicates_are_exact_copies_at_the_expected_rate() -> None:
    chan = channel("duplicate=10%")
    out = simulate(chan, every(0.001))
    counts = chan.counts
    assert 0.088 < counts.duplicated / N < 0.112  # sigma 0.0021
    assert len(out) == N + counts.duplicated == counts.delivered
    numbers = [number(d) for _, d in out]
    assert numbers == sorted(numbers)  # the copy follows the original, nothing else reorders
    assert all(d == datagram(number(d)) for _, d in out)


def test_corruption_flips_exactly_one_bit() -> None:
    chan = channel("corrupt=10%")
    sends = every(0.001)
    out = simulate(chan, sends)
    assert len(out) == N
    flips = [
        bin(int.from_bytes(sent, "big") ^ int.from_bytes(got, "big")).count("1")
        for (_, sent), (_, got) in zip(sends, out, strict=True)
    ]
    assert set(flips) == {0, 1}
    assert flips.count(1) == chan.counts.corrupted
    assert 0.088 < chan.counts.corrupted / N < 0.112
    empty = channel("corrupt=100%")
    empty.send(b"", 0.0)
    assert empty.due(0.0) == [b""]
    assert empty.counts.corrupted == 0


def test_reordered_datagrams_are_overtaken_by_later_ones() -> None:
    chan = channel("reorder=10%,delay=5ms")  # gap: max(5 ms, 10 ms); one datagram a millisecond
    out = simulate(chan, every(0.001))
    order = [number(d) for _, d in out]
    assert sorted(order) == list(range(N))
    # A datagram is late when one sent after it was delivered before it.
    late = set()
    highest = -1
    for i in order:
        if i < highest:
            late.add(i)
        highest = max(highest, i)
    assert len(late) == chan.counts.reordered
    assert 0.088 < len(late) / N < 0.112
    delays = {number(d): at - number(d) * 0.001 for at, d in out}
    for i in late:
        assert delays[i] == pytest.approx(0.015)  # delay + gap


def test_an_explicit_gap() -> None:
    chan = channel("reorder=100%,gap=30ms")
    chan.send(b"a", 0.0)
    assert chan.get_timer() == pytest.approx(0.030)
    assert chan.counts.reordered == 1


@pytest.mark.parametrize("step", [0.001, 0.025])
def test_delay_and_jitter_stay_within_bounds_and_keep_the_order(step: float) -> None:
    chan = channel("delay=40ms,jitter=10ms")
    out = simulate(chan, every(step))
    assert [number(d) for _, d in out] == list(range(N))
    delays = [at - number(d) * step for at, d in out]
    assert min(delays) >= 0.030 - 1e-9
    assert max(delays) <= 0.050 + 1e-9
    if step > 0.020:  # sparse enough that no datagram waits for the one before: uniform
        assert sum(delays) / N == pytest.approx(0.040, abs=0.0003)
        assert min(delays) < 0.0305
        assert max(delays) > 0.0495


def test_jitter_larger_than_the_delay_is_cut_at_zero() -> None:
    chan = channel("delay=1ms,jitter=5ms")
    out = simulate(chan, every(0.010, 2000))
    delays = [at - number(d) * 0.010 for at, d in out]
    assert min(delays) == 0.0
    assert max(delays) <= 0.006 + 1e-9


def test_a_full_channel_drops_and_counts() -> None:
    chan = channel("delay=1s", limit=100)
    for i in range(150):
        chan.send(datagram(i), 0.0)
    assert chan.held == 100
    assert chan.counts.dropped == 50
    assert chan.due(1.0) == [datagram(i) for i in range(100)]
    chan.send(b"later", 1.0)
    assert chan.held == 1


def test_flush_and_discard() -> None:
    chan = channel("delay=1s,jitter=500ms")
    for i in range(10):
        chan.send(datagram(i), i * 0.001)
    assert chan.flush() == [datagram(i) for i in range(10)]
    assert chan.counts.delivered == 10
    assert chan.get_timer() is None
    for i in range(5):
        chan.send(datagram(i), 1.0)
    assert chan.discard() == 5
    assert chan.counts == Counts(sent=15, delivered=10, discarded=5)


def test_seeds_are_derived_the_same_everywhere() -> None:
    # Pinned: a run's seed must give the same fates in every version and process.
    assert derive_seed(1, 0, "forward") == 0x5BD32EB2985B95A7
    assert derive_seed(1, 0, "backward") == 0x59619528EFA494C5
    seeds = {derive_seed(s, f, d) for s in (0, 1) for f in (0, 1) for d in ("forward", "backward")}
    assert len(seeds) == 8
    forward, backward = channel_pair(parse_impairment("loss=50%"), seed=5, flow=2)
    assert forward.seed == derive_seed(5, 2, "forward")
    assert backward.seed == derive_seed(5, 2, "backward")
    assert lost_numbers(forward, 200) != lost_numbers(backward, 200)


def test_counts_add_up() -> None:
    a = Counts(sent=3, lost=1, delivered=2)
    assert a + Counts(sent=1, duplicated=1) == Counts(sent=4, lost=1, duplicated=1, delivered=2)
    assert a.copy() == a
    assert a.copy() is not a


def test_a_limit_below_one_is_refused() -> None:
    with pytest.raises(ValueError, match="limit"):
        ImpairedChannel(Impairment(), 0, limit=0)


probabilities = st.sampled_from([0.0, 0.1, 0.5, 1.0])
times = st.sampled_from([0.0, 0.001, 0.02])


@given(
    imp=st.builds(
        Impairment,
        loss=probabilities,
        delay=times,
        jitter=times,
        reorder=probabilities,
        gap=st.none() | times,
        duplicate=probabilities,
        corrupt=probabilities,
    ),
    seed=st.integers(0, 2**64),
    gaps=st.lists(st.sampled_from([0.0, 0.0005, 0.003]), max_size=60),
    limit=st.integers(1, 20),
)
def test_every_datagram_is_accounted_for_and_none_comes_early(
    imp: Impairment, seed: int, gaps: list[float], limit: int
) -> None:
    chan = ImpairedChannel(imp, seed, limit=limit)
    sends = [(t, datagram(i)) for i, t in enumerate(itertools.accumulate(gaps))]
    sent_at = {data: t for t, data in sends}
    out: list[tuple[float, bytes]] = []
    pending = sends[::-1]
    while pending or chan.get_timer() is not None:
        timer = chan.get_timer()
        if pending and (timer is None or pending[-1][0] <= timer):
            now, data = pending.pop()
            chan.send(data, now)
        else:
            assert timer is not None
            now = timer
        out.extend((now, d) for d in chan.due(now))
        c = chan.counts
        assert c.sent - c.lost + c.duplicated == c.delivered + c.dropped + c.discarded + chan.held
        assert chan.held <= limit
    upper = imp.delay + imp.jitter + (imp.reorder_gap if imp.reorder else 0.0)
    for at, data in out:
        if imp.corrupt == 0:  # else one flipped bit can make one datagram look like another
            assert sent_at[data] <= at <= sent_at[data] + upper + 1e-9
    assert len(out) == chan.counts.delivered
