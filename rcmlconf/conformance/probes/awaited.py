"""Waits for what a case expects from its peer, allowing for holds of the harness's loop.

The harness's event loop may be held up, for example on a loaded machine. A hold delays what the
harness reads by the hold's length at most. Several holds delay it by their sum (D-RSP-26).

`must_come` waits for something the peer must send. `came` does the same for one datagram.

- specs/ sets a bound by which the peer must send it. The case waits for a window that ends well
  past that bound. So this first wait does not judge the peer's timing.
- If nothing came in the window, the case waits as long again. This tells how late it comes.
- Then a timing check fails. It is excused only if the harness's holds add up to the lateness.
  If nothing came at all, the lateness is how long the case waited past the window.
- So, on a machine with no holds, a peer that never sends fails. A peer that sends only after
  the window fails too.

`may_come` waits for something the peer may or may not send. The spec sets no bound for it.

- The case waits for a window, and then longer by the sum of the harness's holds.
- What a held harness did not read in its window, it reads in that extra time.
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

#: Seconds (times --timeout-scale) of the case's time that the second wait leaves over.
#: In that time the check gives its own verdict, which says what was late. Without it, the
#: case's timeout would end the case with a fail that does not say.
_SPARE = 0.1


def _room(ctx: Context) -> float:
    """Seconds of the case's time that a wait past its window may take."""
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
    """What `look` finds within `window`. It must come.

    If it does not come, the case fails with `requirement` and `expected`. `instead` says what
    came in its place.

    `again` is the look for the second wait. It looks from where `look` began. It defaults to
    `look` itself. A look that sends a packet first needs an `again` that does not send again.

    `at` says when the found thing came, in `probe`'s loop time. By default that is when the
    look returned.
    """
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
    """The first datagram of `kinds` for which `where` holds. It must come (`must_come`).

    The search starts at `after`. By default it starts now. If `send` is given, it sends its
    packet first, as `answer_to` does.

    The window is `wait`. By default it is the probe's wait.

    `expected` cites the bound in specs/ by which the datagram is due.
    """
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
    """What `look` finds within `window`, or None if it does not come.

    `since` is the loop time when the case asked for it. After the window, the case waits on
    for as long as the holds of the harness's loop since `since` add up to. The holds may grow
    while it waits; the wait grows with them.

    Inconclusive if the case's time runs out before the holds are waited out. The holds may
    have hidden `what`.
    """
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
