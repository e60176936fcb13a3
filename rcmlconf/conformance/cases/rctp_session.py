"""rctp/session: CONNECT and the session it opens, the Session field, BYE, the session timeout,
and what the end of a session releases (specs/rctp-2.0.md D-RCTP-11, D-RCTP-13, R-RCTP-17 to
R-RCTP-23, R-RCTP-36).

The last cases check what a server serves one peer address (D-RCTP-32, R-RCTP-67): at least 64
connections and 32 sessions at once, 503 for a CONNECT beyond its cap, and 10 s for a slow
client. A client, and a conformance harness, can count on that floor.
"""

from __future__ import annotations

import asyncio
import itertools

from rcmlconf.conformance.context import Context, expect_answer
from rcmlconf.conformance.picks import STRANGER, read_target
from rcmlconf.conformance.probes.control import CLOSED, ControlProbe, Fields, describe
from rcmlconf.conformance.probes.lost import RESET
from rcmlconf.conformance.probes.stream import open_stream
from rcmlconf.conformance.probes.stream_access import (
    heartbeat_request,
    readable_stream,
    stream_request,
)
from rcmlconf.conformance.registry import case
from rcmlconf.conformance.verdicts import Failed, Inconclusive
from rcmlconf.errors import ValueTextError
from rcmlconf.rcml.model import Permission
from rcmlconf.rctp.fields import SessionField, parse_session, same_token
from rcmlconf.rctp.messages import VERSION, Request, Response
from rcmlconf.rctp.targets import format_target

#: R-RCTP-23: how long the sender of BYE waits for its answer.
BYE_WAIT = 5.0


@case(
    "rctp/session/connect-session-field",
    "CONNECT is answered 200 with Session: an ID of 8 to 64 characters and a timeout",
    ["R-RCTP-18"],
)
async def connect_session_field(ctx: Context) -> None:
    probe = await ctx.control()
    answer = await probe.connect(ctx.target.site_path)
    ctx.expect_status(answer, 200)
    _session_field(ctx, answer)


@case(
    "rctp/session/ids-differ",
    "Sessions of different connections get different IDs that do not look sequential",
    ["R-RCTP-18", "R-RCTP-19"],
)
async def ids_differ(ctx: Context) -> None:
    ids: list[str] = []
    for _ in range(4):
        probe = await ctx.control()
        answer = await probe.connect(ctx.target.site_path)
        ctx.expect_status(answer, 200)
        ids.append(_session_field(ctx, answer)[0])
    ctx.expect(len(set(ids)) == len(ids), "four different session IDs", ", ".join(ids), "R-RCTP-19")
    for one, other in itertools.combinations(ids, 2):
        differing = _differing(one, other)
        ctx.expect(
            differing >= max(len(one), len(other)) // 4,
            "unguessable session IDs (D-RCTP-11): any two differ in a quarter of their characters",
            f"{one} and {other} differ in {differing}",
            "R-RCTP-18",
        )


@case(
    "rctp/session/session-before-connect",
    "A request before CONNECT is answered 454 even with a Session field, another connection's "
    "session's included",
    ["R-RCTP-17"],
)
async def session_before_connect(ctx: Context) -> None:
    probe = await ctx.control()
    await _foreign_sessions(ctx, probe, "READ before CONNECT")
    expect_answer(ctx, await probe.connect(ctx.target.site_path), 200, "CONNECT afterwards")


@case(
    "rctp/session/wrong-session",
    "A request naming another session, unknown, another connection's or its own ID in other letter"
    " case, is answered 454 and the connection goes on",
    ["R-RCTP-19"],
)
async def wrong_session(ctx: Context) -> None:
    probe = await ctx.session()
    await _foreign_sessions(ctx, probe, "READ")
    # Session IDs are compared exactly (D-RCTP-30): the session's own ID in other letter case
    # names another session.
    assert probe.session is not None
    swapped = probe.session.swapcase()
    if swapped == probe.session:
        ctx.cannot_check("a session ID in other letter case: the server's ID has no letter")
    else:
        answer = await probe.request("READ", read_target(ctx), [("Session", swapped)])
        expect_answer(ctx, answer, 454, f"READ with Session: {swapped}, its ID in other case")
    answer = await probe.request("READ", read_target(ctx))
    expect_answer(ctx, answer, 200, "READ with the session")


@case(
    "rctp/session/session-with-timeout",
    "A request whose Session carries the timeout parameter, in any letter case, names the session"
    " by its ID: answered as without it",
    ["R-RCTP-19", "R-RCTP-59"],
)
async def session_with_timeout(ctx: Context) -> None:
    # §2.1: Session = session-id [ ";" OWS "timeout" "=" 1*5DIGIT ], in any message; a client
    # may send back what CONNECT's answer gave, and `timeout` in any letter case (D-RCTP-30).
    probe = await ctx.session()
    normal = read_target(ctx)
    for parameter, requirement in _WITH_TIMEOUT:
        field = f"{probe.session}{parameter}"
        answer = await probe.request("READ", normal, [("Session", field)])
        expect_answer(ctx, answer, 200, f"READ {normal} with Session: {field}", requirement)


#: The timeout parameters session-with-timeout sends, and what a READ refused with each breaks.
_WITH_TIMEOUT = (
    (";timeout=60", "R-RCTP-19"),
    ("; timeout=60", "R-RCTP-19"),
    (";TimeOut=60", "R-RCTP-59"),
)


@case(
    "rctp/session/missing-session",
    "A request without Session after CONNECT is answered 454 and the connection goes on",
    ["R-RCTP-19"],
)
async def missing_session(ctx: Context) -> None:
    probe = await ctx.session()
    normal = read_target(ctx)
    await probe.send(_sessionless(probe, "READ", normal))
    expect_answer(ctx, await probe.response(), 454, "READ without Session")
    expect_answer(ctx, await probe.request("READ", normal), 200, "READ with the session")


@case(
    "rctp/session/connect-refresh",
    "CONNECT with the current Session is answered 200, naming the same session",
    ["R-RCTP-22"],
)
async def connect_refresh(ctx: Context) -> None:
    probe = await ctx.session()
    session = probe.session
    answer = await probe.connect(ctx.target.site_path)
    ctx.expect_status(answer, 200)
    given = (answer.headers.get("Session") or "").split(";")[0].strip()
    ctx.expect(given == session, f"Session: {session}", f"Session: {given}")


@case(
    "rctp/session/second-connect",
    "CONNECT without Session on a connection that has a session is answered 455; the session stays",
    ["R-RCTP-20"],
)
async def second_connect(ctx: Context) -> None:
    probe = await ctx.session()
    site = ctx.target.site_path
    await probe.send(_sessionless(probe, "CONNECT", site))
    expect_answer(ctx, await probe.response(), 455, "a second CONNECT without Session")
    normal = read_target(ctx)
    expect_answer(ctx, await probe.request("READ", normal), 200, "READ with the first session")


@case(
    "rctp/session/connect-unknown-site",
    "CONNECT to a site path that names no robot is answered 404 and opens no session",
    ["R-RCTP-26", "R-RCTP-17"],
)
async def connect_unknown_site(ctx: Context) -> None:
    probe = await ctx.control()
    site = ctx.target.site_path
    nowhere = site.rstrip("/") + "/rcmlconf-no-robot"
    expect_answer(ctx, await probe.connect(nowhere), 404, f"CONNECT {nowhere}", "R-RCTP-26")
    normal = read_target(ctx)
    answer = await probe.request("READ", normal, [("Session", STRANGER)])
    expect_answer(ctx, answer, 454, "READ after the refused CONNECT", "R-RCTP-17")
    expect_answer(ctx, await probe.connect(site), 200, f"CONNECT {site}")


@case(
    "rctp/session/bye-by-client",
    "The client's BYE of * is answered 200 with its CSeq, and nothing else is sent",
    ["R-RCTP-23", "R-RCTP-3"],
)
async def bye_by_client(ctx: Context) -> None:
    probe = await ctx.session()
    # With its CSeq: the probe matches every answer to its request's (R-RCTP-3).
    ctx.expect_status(await probe.request("BYE", "*"), 200)
    outcome = await probe.outcome(0.5 * ctx.scale)
    ctx.expect(outcome in ("closed", "silent"), "nothing after the answer to BYE", outcome)


@case(
    "rctp/session/bye-releases",
    "The privileges of a session that ends with the client's BYE are free for another session",
    ["R-RCTP-36"],
    serial=True,
)
async def bye_releases(ctx: Context) -> None:
    holder, other, path = await _held_elsewhere(ctx)
    answer = await holder.request("BYE", "*")
    if answer.status != 200:  # rctp/session/bye-by-client fails such a server
        raise Inconclusive(f"BYE was answered {answer.status} {answer.reason}")
    await _acquired_soon(ctx, other, path, "after the holder's BYE")


@case(
    "rctp/session/close-releases",
    "The privileges of a session whose connection closes are free for another session",
    ["R-RCTP-36"],
    serial=True,
)
async def close_releases(ctx: Context) -> None:
    holder, other, path = await _held_elsewhere(ctx)
    holder.close()
    await _acquired_soon(ctx, other, path, "after the holder's connection closed")


@case(
    "rctp/session/timeout-bye",
    "A session without requests for its timeout gets the server's BYE * (Reason: timeout, CSeq "
    "1); answered, the server closes",
    ["R-RCTP-21", "R-RCTP-4", "R-RCTP-19", "R-RCTP-23"],
    timeout=10.0,
    waits_session=True,
)
async def timeout_bye(ctx: Context) -> None:
    probe, timeout, started = await _timed_session(ctx)
    bye = await _server_bye(ctx, probe, timeout, started)
    given = bye.headers.get("Reason")
    ctx.expect(same_token(given, "timeout"), "Reason: timeout", f"Reason: {given}", "R-RCTP-21")
    given = bye.headers.get("CSeq")
    ctx.expect(given == "1", "CSeq: 1, the server's first request", f"CSeq: {given}", "R-RCTP-4")
    given = bye.headers.get("Session")
    ctx.expect(
        given == probe.session, f"Session: {probe.session}", f"Session: {given}", "R-RCTP-19"
    )
    await probe.answer(bye)
    outcome = await probe.outcome(ctx.wait)
    ctx.expect(
        outcome == "closed", "the connection closed once BYE was answered", outcome, "R-RCTP-23"
    )


@case(
    "rctp/session/keepalive",
    "A READ and a CONNECT refresh, each before the timeout passes, keep the session open past it",
    ["R-RCTP-21", "R-RCTP-22"],
    timeout=15.0,
    waits_session=True,
)
async def keepalive(ctx: Context) -> None:
    probe, timeout, _ = await _timed_session(ctx)
    normal = read_target(ctx)
    for method, target in (("READ", normal), ("CONNECT", ctx.target.site_path)):
        outcome = await probe.outcome(0.6 * timeout)
        ctx.expect(outcome == "silent", "nothing before the timeout", outcome, "R-RCTP-21")
        await probe.send(probe.request_bytes(method, target))
        found = await probe.message()
        ctx.expect(
            isinstance(found, Response) and found.status == 200,
            f"the answer 200 to {method}",
            describe(found),
            "R-RCTP-21" if method == "READ" else "R-RCTP-22",
        )
    outcome = await probe.outcome(timeout - 0.5)
    ctx.expect(
        outcome == "silent",
        f"no BYE within {timeout - 0.5:g} s of the last request",
        outcome,
        "R-RCTP-21",
    )


@case(
    "rctp/session/stream-keeps-alive",
    "A session whose client sends only data-stream packets (heartbeats of a playing stream) past"
    " its timeout is kept: no BYE",
    ["R-RCTP-21"],
    timeout=10.0,
    waits_session=True,
)
async def stream_keeps_alive(ctx: Context) -> None:
    probe, timeout, _ = await _timed_session(ctx)
    stream = await open_stream(ctx, probe)
    set_up = await stream.setup(probe, readable_stream(ctx))
    await stream_request(ctx, probe, "GO", set_up)
    # D-RCTP-11: any data-stream packet from the client keeps the session alive, as a request
    # does; a server that times sessions by their requests alone BYEs a client that streams.
    every = timeout / 3
    loop = asyncio.get_running_loop()
    # Past the timeout since GO, the last request, by what the case's time leaves (at least the
    # 5 s a session case has beyond --session-wait, less what it took to get here).
    until = loop.time() + timeout + min(timeout / 2, 2.0, ctx.left - 1.0)
    while (left := until - loop.time()) > 0:
        stream.send_flow(heartbeat_request(stream.next_request_id()))
        outcome = await probe.outcome(min(every, left))
        ctx.expect(
            outcome == "silent",
            f"no BYE while a heartbeat comes every {every:g} s and no request",
            outcome,
            "R-RCTP-21",
        )


@case(
    "rctp/session/bye-error-answer-closes",
    "The server's BYE answered with an error status is answered all the same: the server closes",
    ["R-RCTP-23"],
    timeout=10.0,
    waits_session=True,
)
async def bye_error_answer_closes(ctx: Context) -> None:
    probe, timeout, started = await _timed_session(ctx)
    bye = await _server_bye(ctx, probe, timeout, started)
    await probe.answer(bye, 454, "Session Not Found")
    outcome = await probe.outcome(ctx.wait)
    ctx.expect(outcome == "closed", "the connection closed once BYE was answered", outcome)


@case(
    "rctp/session/bye-unanswered-closes",
    "The server's BYE left unanswered: the server closes the connection 5 seconds later",
    ["R-RCTP-23"],
    timeout=15.0,
    waits_session=True,
)
async def bye_unanswered_closes(ctx: Context) -> None:
    probe, timeout, started = await _timed_session(ctx)
    await _server_bye(ctx, probe, timeout, started)
    loop = asyncio.get_running_loop()
    asked = loop.time()
    outcome = await probe.outcome(BYE_WAIT + 1.5 * ctx.scale)
    waited = loop.time() - asked
    ctx.expect(
        outcome == "closed" and waited >= BYE_WAIT - 0.5,
        f"the connection closed {BYE_WAIT:g} s after the unanswered BYE",
        f"{outcome} after {waited:.2f} s",
    )


# -- helpers -----------------------------------------------------------------------------------


def _differing(one: str, other: str) -> int:
    """In how many places two IDs differ, compared from the start."""
    return sum(a != b for a, b in zip(one, other, strict=False)) + abs(len(one) - len(other))


def _session_field(ctx: Context, answer: Response) -> tuple[str, int]:
    """The session ID and timeout of CONNECT's answer (R-RCTP-18)."""
    given = answer.headers.get("Session")
    try:  # the core's reading of §2.1: `timeout` in any letter case (D-RCTP-30)
        found: SessionField | None = parse_session(given or "")
    except ValueTextError:
        found = None
    ctx.expect(
        found is not None and found.timeout is not None and found.timeout > 0,
        "Session: id;timeout=seconds, the ID 8 to 64 of A-Z a-z 0-9 $ - _ . +",
        f"Session: {given}",
        "R-RCTP-18",
    )
    assert found is not None
    assert found.timeout is not None
    return found.id, found.timeout


async def _timed_session(ctx: Context) -> tuple[ControlProbe, int, float]:
    """A session, its timeout, and when CONNECT was sent; inconclusive when the timeout is longer
    than the case can wait."""
    probe = await ctx.control()
    started = asyncio.get_running_loop().time()
    answer = await probe.connect(ctx.target.site_path)
    if answer.status != 200 or probe.session is None:
        raise Inconclusive(f"CONNECT was answered {answer.status} {answer.reason}")
    _, timeout = _session_field(ctx, answer)
    return probe, ctx.waited_session(timeout), started


async def _server_bye(ctx: Context, probe: ControlProbe, timeout: int, started: float) -> Request:
    """The server's BYE of a session left alone: not before its timeout, and soon after it."""
    loop = asyncio.get_running_loop()
    try:
        found = await probe.message(timeout + 1.5 * ctx.scale - (loop.time() - started))
    except Failed as failed:
        if failed.requirement != "R-RCTP-5":
            raise
        expected = f"BYE * once the timeout of {timeout} s passed"
        raise Failed(
            "R-RCTP-21", expected, f"nothing after {loop.time() - started:.2f} s"
        ) from None
    waited = loop.time() - started
    ctx.expect(
        isinstance(found, Request) and found.method == "BYE" and found.target == "*",
        f"BYE * once the timeout of {timeout} s passed",
        describe(found),
        "R-RCTP-21",
    )
    ctx.expect(
        waited >= timeout - 0.2,
        f"BYE once the timeout of {timeout} s passed",
        f"BYE after {waited:.2f} s",
        "R-RCTP-21",
    )
    assert isinstance(found, Request)
    return found


async def _held_elsewhere(ctx: Context) -> tuple[ControlProbe, ControlProbe, str]:
    """A session holding a path, and another session refused it (471)."""
    access = ctx.access(permission=Permission.WRITE)
    path = format_target(access.path)
    holder = await ctx.session()
    answer = await holder.request("ACQUIRE", path)
    if answer.status != 200:
        raise Inconclusive(f"ACQUIRE {access.path} was answered {answer.status} {answer.reason}")
    other = await ctx.session()
    answer = await other.request("ACQUIRE", path)
    if answer.status != 471:
        raise Inconclusive(
            f"ACQUIRE {access.path} held by another session was answered {answer.status}"
        )
    return holder, other, path


async def _acquired_soon(ctx: Context, probe: ControlProbe, path: str, when: str) -> None:
    """ACQUIRE succeeds within a second (the server may take a moment to see the session end);
    then it is released again."""
    loop = asyncio.get_running_loop()
    deadline = loop.time() + ctx.scale
    while True:
        answer = await probe.request("ACQUIRE", path)
        if answer.status == 200 or loop.time() > deadline:
            break
        await asyncio.sleep(0.05)
    expect_answer(ctx, answer, 200, f"ACQUIRE {path} {when}")
    await probe.request("RELEASE", path)


async def _foreign_sessions(ctx: Context, probe: ControlProbe, what: str) -> None:
    """READs naming a session no server hands out, then another connection's, are answered 454
    (`what` says which READ)."""
    other = await ctx.session()
    assert other.session is not None
    normal = read_target(ctx)
    for session in (STRANGER, other.session):
        answer = await probe.request("READ", normal, [("Session", session)])
        expect_answer(ctx, answer, 454, f"{what} with Session: {session}")


def _sessionless(probe: ControlProbe, method: str, target: str, fields: Fields = ()) -> bytes:
    """A request with the next CSeq and without Session."""
    probe.cseq += 1
    lines = [f"{method} {target} {VERSION}", f"CSeq: {probe.cseq}"]
    lines += [f"{name}: {value}" for name, value in fields]
    return ("\r\n".join(lines) + "\r\n\r\n").encode()


# -- what a server serves one peer address (D-RCTP-32, R-RCTP-67) ------------------------------


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
