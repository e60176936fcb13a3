"""What a case awaits from its peer, as a harness whose event loop may be held up reads it
(D-RSP-26: a hold of the harness's loop delays what it reads by its length at most, several by
their sum).

- `must_come`, and `came` for a datagram: what the peer must send, awaited within a window that
  lies well past the bound of specs/ it sends it by (the case does not judge its timing). When
  nothing came in it, the case waits as long again to learn how late it comes: a timing check,
  excused as far as the harness's holds add up to how late it came, or, when it never came, to
  how long the case waited past the window. On a machine that holds nothing, a peer that never
  sends it fails, and so does one that sends it that late.
- `may_come`: what the peer may send or not (the spec sets no bound for it), awaited within a
  window and as much longer as the harness's holds add up to: what a held harness did not read
  in its window, it reads then.
"""

from __future__ import annotations

from collections.abc import Awaitable, Callable, Iterable
from typing import TypeVar

from rcmlconf.conformance.context import Context
from rcmlconf.conformance.probes.datagrams import DatagramLog
from rcmlconf.conformance.probes.held import held
from rcmlconf.conformance.probes.rsp_datagram import Datagram, Where
from rcmlconf.conformance.verdicts import Inconclusive
from rcmlconf.rsp.codec import PacketType

T = TypeVar("T")
#: A look for what the case awaits: given how long to wait (seconds), what came, or None.
Look = Callable[[float], Awaitable[T | None]]

#: Seconds (times --timeout-scale) of the case's time that the second window leaves for the
#: verdict: the check's own, not the case's timeout (a fail that says nothing of what was late).
_SPARE = 0.1


def _room(ctx: Context) -> float:
    """Seconds a wait past its window may take of the case's time."""
    return max(ctx.left - _SPARE * ctx.scale, 0.0)


async def must_come(
    ctx: Context,
    probe: DatagramLog,
    look: Look[T],
    window: float,
    expected: str,
    requirement: str | None = None,
    *,
    again: Look[T] | None = None,
    at: Callable[[T], float] | None = None,
    instead: Callable[[], str] | None = None,
) -> T:
    """What `look` finds within `window`, which must come (Failed: `requirement`, `expected`;
    `instead` says what came in its place). `again` looks for it from where `look` began (by
    default `look` itself; a look that sends first must not send again); `at` says when what it
    found came, in `probe`'s loop time (by default: when the look returned)."""
    since = probe.now
    found = await look(window)
    if found is None:
        due = since + window
        late = await (again or look)(min(window, _room(ctx)))
        seen = at(late) if late is not None and at is not None else probe.now
        got = (
            f"none within {(seen - since) * 1000:.0f} ms"
            if late is None
            else f"none within {window * 1000:.0f} ms: it came {(seen - since) * 1000:.0f} ms after"
        )
        ctx.expect(
            False,
            expected,
            got + (f"; {instead()}" if instead is not None else ""),
            requirement,
            timing=True,
            by=seen - due,
        )
    assert found is not None  # expect failed the case otherwise
    return found


async def came(
    ctx: Context,
    probe: DatagramLog,
    kinds: PacketType | Iterable[PacketType],
    expected: str,
    requirement: str | None = None,
    *,
    send: Callable[[], object] | None = None,
    after: int | None = None,
    where: Where | None = None,
    wait: float | None = None,
    instead: Callable[[], str] | None = None,
) -> Datagram:
    """The first datagram of `kinds` for which `where` holds from `after` (by default: from now,
    `send` sending its packet first as `answer_to` does), which must come (`must_come`) within
    `wait` (the probe's by default); `expected` cites the bound of specs/ it is due by."""
    start = probe.mark() if after is None else after

    def look(seconds: float) -> Awaitable[Datagram | None]:
        return probe.next(kinds, after=start, where=where, wait=seconds)

    def answer(seconds: float) -> Awaitable[Datagram | None]:
        assert send is not None
        return probe.answer_to(send, kinds, where=where, wait=seconds)

    return await must_come(
        ctx,
        probe,
        look if send is None else answer,
        probe.wait if wait is None else wait,
        expected,
        requirement,
        again=look,
        at=lambda found: found.at,
        instead=instead,
    )


async def may_come(
    ctx: Context, probe: DatagramLog, look: Look[T], since: float, window: float, what: str
) -> T | None:
    """What `look` finds within `window`, and past it for as long as the holds of the harness's
    loop since loop time `since` (when the case asked for it) add up to, as they grow while it
    waits; None if it did not come. Inconclusive when the case's time ran out before the holds
    were waited out (they may have hidden `what`)."""
    due = probe.now + window
    found = await look(window)
    while found is None and probe.now < due + held(ctx, since) and _room(ctx) > 0:
        found = await look(min(due + held(ctx, since) - probe.now, _room(ctx)))
    hold = held(ctx, since)
    if found is None and probe.now < due + hold:
        raise Inconclusive(
            f"no {what} within {probe.now - since:.2f} s; but the harness's event loop was held"
            f" {hold * 1000:.0f} ms: it may have hidden it"
        )
    return found
