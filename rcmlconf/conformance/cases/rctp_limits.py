"""rctp/session: what a server serves one peer address — at least 64 connections and 32 sessions
at once, 503 for a CONNECT beyond its cap of sessions, 10 s for a client to be slow — so that a
client, and a conformance harness, can count on a floor (specs/rctp-2.0.md D-RCTP-32,
R-RCTP-67)."""

from __future__ import annotations

import asyncio

from rcmlconf.conformance.context import Context
from rcmlconf.conformance.probes.control import CLOSED, ControlProbe, describe
from rcmlconf.conformance.probes.lost import RESET
from rcmlconf.conformance.registry import case
from rcmlconf.conformance.verdicts import Failed
from rcmlconf.rctp.messages import Response

#: D-RCTP-32's floors: a server serves at least this many connections, and sessions, of one
#: peer address at once.
CONNECTIONS = 64
SESSIONS = 32
#: How slow rctp/session/slow-client-kept is, against R-RCTP-67's floor of 10 s (not scaled:
#: the floor is the server's promise, not a time the server takes).
SLOW_FOR = 8.0
#: The answers to a CONNECT of a peer below the floors: its session, or 503 beyond a cap.
_SERVED = ("200", "503")


@case(
    "rctp/session/peer-floors",
    f"{CONNECTIONS} connections of one address at once each send CONNECT: all are answered, at"
    f" least {SESSIONS} with 200 (their sessions then served together), the rest 503; one"
    " connection more, if taken, is answered 200 or 503",
    ["R-RCTP-67"],
    timeout=10.0,
    exclusive=True,
)
async def peer_floors(ctx: Context) -> None:
    # Alone in the run (`exclusive`, after the other cases): their connections come from the
    # harness's address too and would count against the server's caps. Alone, its connections
    # fill no cap in all (at least 64, D-RCTP-32), so none is closed to make room; the one more
    # of `_beyond` comes once all hold sessions, which are never closed so.
    probes: list[ControlProbe] = []
    try:
        await _floors(ctx, probes)
    except Failed:
        # D-RCTP-33: the server may count the sessions and connections of the cases before
        # for a second after they closed; once more, then, and that try is judged.
        for probe in probes:
            probe.close()
        probes.clear()
        await asyncio.sleep(ctx.scale)
        await _floors(ctx, probes)
    await _beyond(ctx, len([p for p in probes if p.session is not None]))


async def _floors(ctx: Context, probes: list[ControlProbe]) -> None:
    """CONNECTIONS connections opened one after another (into `probes`), then a CONNECT on each
    at once: each answered 200 or 503 (D-RCTP-32), SESSIONS at least 200; then a refresh of
    each session at once, each answered 200 (R-RCTP-22: every session still served)."""
    site = ctx.target.site_path
    for _ in range(CONNECTIONS):
        probes.append(await ctx.control())
    found = await asyncio.gather(*(_connected(probe, site) for probe in probes))
    opened, refused = found.count("200"), found.count("503")
    others = [f"connection {n}: {got}" for n, got in enumerate(found, 1) if got not in _SERVED]
    ctx.expect(
        not others,
        f"an answer 200 or 503 (beyond a cap of sessions) to CONNECT on each of {CONNECTIONS}"
        " connections of one address open at once",
        _first(others),
        "R-RCTP-67",
    )
    ctx.expect(
        opened >= SESSIONS,
        f"at least {SESSIONS} CONNECTs of {CONNECTIONS} answered 200",
        f"{opened} answered 200, {refused} 503",
        "R-RCTP-67",
    )
    held = [probe for probe in probes if probe.session is not None]
    found = await asyncio.gather(*(_connected(probe, site) for probe in held))
    lost = [f"session {n}: {got}" for n, got in enumerate(found, 1) if got != "200"]
    ctx.expect(
        not lost,
        f"the refresh of each of the {opened} sessions open at once answered 200",
        _first(lost),
        "R-RCTP-67",
    )


async def _beyond(ctx: Context, opened: int) -> None:
    """The 503 beyond the server's cap of sessions: seen among the CONNECTIONS if fewer than all
    were opened, else sought with one connection more."""
    if opened < CONNECTIONS:
        return  # the rest were answered 503 (`_floors`)
    probe = await ctx.control()
    got = await _connected(probe, ctx.target.site_path)
    if got == "200":
        ctx.cannot_check(
            f"the 503 beyond a cap of sessions: the server took {CONNECTIONS + 1} sessions of"
            " one address, and has no cap the case reaches"
        )
    elif got in (CLOSED, RESET):
        ctx.cannot_check(
            f"the 503 beyond a cap of sessions: the server closed connection {CONNECTIONS + 1},"
            " beyond its cap of connections (D-RCTP-32), before a CONNECT beyond its sessions'"
        )
    else:
        ctx.expect(
            got == "503",
            f"the answer 503 to a CONNECT beyond the server's cap of sessions, or 200 below it,"
            f" with {CONNECTIONS} sessions of the address open",
            got,
            "R-RCTP-67",
        )


def _first(wrong: list[str]) -> str:
    """The first three of `wrong`, and how many more."""
    more = f"; and {len(wrong) - 3} more" if len(wrong) > 3 else ""
    return "; ".join(wrong[:3]) + more


async def _kept(seconds: float, *probes: ControlProbe) -> None:
    """`seconds` pass, or fewer once the target ends a connection of `probes` (closed or
    reset): it broke the floor then, and no answer can come on it to wait for."""
    watches = [asyncio.ensure_future(probe.closes(seconds)) for probe in probes]
    try:
        await asyncio.wait(watches, timeout=seconds, return_when=asyncio.FIRST_COMPLETED)
    finally:
        for watch in watches:
            watch.cancel()
        await asyncio.gather(*watches, return_exceptions=True)


async def _connected(probe: ControlProbe, site: str) -> str:
    """The status of the answer to CONNECT (which keeps its session), or what came instead."""
    try:
        return str((await probe.connect(site)).status)
    except Failed as failed:
        return failed.actual


@case(
    "rctp/session/slow-client-kept",
    f"A connection whose CONNECT comes {SLOW_FOR:g} s after it opened, and one whose CONNECT"
    f" takes {SLOW_FOR:g} s to arrive, are both answered: D-RCTP-32 closes slow ones at 10 s",
    ["R-RCTP-67"],
    timeout=SLOW_FOR + 5.0,
)
async def slow_client_kept(ctx: Context) -> None:
    # The floors of connections and sessions, and the 503, are peer-floors': it runs alone.
    # These two connections hold no session for SLOW_FOR s: a server whose connections fill its
    # cap in all may close them sooner, to make room (D-RCTP-32). The harness's cases beside
    # this one hold fewer than the 64 connections such a cap is at least: they never fill it.
    quiet, slow = await ctx.control(), await ctx.control()
    # Without a session yet, so that no session timeout is in play: the slow CONNECT's first
    # bytes now and the rest in SLOW_FOR seconds, the quiet one's all then.
    request = slow.request_bytes("CONNECT", ctx.target.site_path)
    await slow.send(request[:9])
    await _kept(SLOW_FOR, quiet, slow)
    await slow.send(request[9:])
    await quiet.send(quiet.request_bytes("CONNECT", ctx.target.site_path))
    for probe, what in (
        (quiet, f"CONNECT sent {SLOW_FOR:g} s after the connection opened"),
        (slow, f"a CONNECT whose head took {SLOW_FOR:g} s, from the connection's opening"),
    ):
        found = await probe.message()
        ctx.expect(
            isinstance(found, Response) and found.status == 200,
            f"the answer 200 to {what}",
            describe(found),
            "R-RCTP-67",
        )
