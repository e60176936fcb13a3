"""Commands that run until Ctrl-C, a duration, or the server's end (`acquire`, `stream`, `watch`).

Each prints what the session hears as it arrives — values on stdout, what happens to the stream
or session on stderr — and finishes cleanly however it ends: the stream stopped, the privilege
released, BYE said. When the server ends the stream or the session first, the command says so and
exits 1 (except `watch`, for which the server's BYE is one more thing to show). This module holds
what they share, and `acquire`, which is nothing more.
"""

from __future__ import annotations

from datetime import datetime

from rcmlconf.cli.client.running import Options, Work
from rcmlconf.cli.interrupts import Interrupts
from rcmlconf.reference.client.adapter import Client
from rcmlconf.reference.client.session import ClientEvent, Closed


async def next_event(
    client: Client, interrupts: Interrupts, deadline: float | None
) -> ClientEvent | None:
    """The session's next event; None at Ctrl-C, at `deadline` (loop time) or once the session
    is over (its last event is `Closed`)."""
    if interrupts.count:
        return None
    left = None if deadline is None else deadline - client.loop.time()
    if left is not None and left <= 0:
        return None
    return await interrupts.race(client.next_event(left))


def deadline_after(client: Client, seconds: float | None) -> float | None:
    return None if seconds is None else client.loop.time() + seconds


def clock_text(unix: float) -> str:
    """A time of day to the millisecond, local time: enough to tell 20 ms packets apart."""
    return datetime.fromtimestamp(unix).strftime("%H:%M:%S.%f")[:-3]


def how_long(seconds: float | None) -> str:
    return "until Ctrl-C" if seconds is None else f"for {seconds:g} s (Ctrl-C stops sooner)"


# -- acquire -----------------------------------------------------------------------------------


def plan_acquire(options: Options, path: str, hold: float | None) -> Work:
    output = options.output

    async def acquire(client: Client) -> int:
        with Interrupts() as interrupts:
            await client.acquire(path)
            output.notice(f"acquired {path}; holding it {how_long(hold)}")
            deadline = deadline_after(client, hold)
            while (event := await next_event(client, interrupts, deadline)) is not None:
                if isinstance(event, Closed):
                    output.problem("client", f"lost {path}: {event.reason}")
                    return 1
        await client.release(path)
        output.notice(f"released {path}")
        return 0

    return acquire
