"""rctp/priv: the access privilege — ACQUIRE and RELEASE, who may WRITE, and how the privilege
ends (specs/rctp-2.0.md §4 D-RCTP-16, R-RCTP-33 to R-RCTP-37).

The privilege is the whole server's state: every case that can be granted one runs alone
(`serial`), starts once no session holds anything (`probes.nodes.sessions`: the sessions of the
case before end when the server reads their closed connections, R-RCTP-36), and ends its own
sessions (the context closes them). Paths are picked from the robot's RCML, never named: a data
node, its access, and the group (or the whole tree) above that.
"""

from __future__ import annotations

import asyncio
import socket
from typing import NamedTuple

from rcmlconf.conformance.context import Context
from rcmlconf.conformance.picks import RW, Named, missing_path, parent_of, pick
from rcmlconf.conformance.probes.control import ControlProbe
from rcmlconf.conformance.probes.nodes import acquire, check_allow, read, sessions, write
from rcmlconf.conformance.registry import case
from rcmlconf.conformance.verdicts import Inconclusive, NotApplicable
from rcmlconf.rcml.model import AccessNode, AccessType, Permission
from rcmlconf.rctp.fields import Transport
from rcmlconf.rctp.messages import Response
from rcmlconf.rctp.targets import ROOT, STAR, format_target

#: How long a case waits for a closed connection to end its session on the server.
_CLOSE_WAIT = 1.0
#: How often it asks meanwhile.
_POLL = 0.02
#: Rounds of the ACQUIRE race.
_RACES = 4


def _writable(ctx: Context) -> Named:
    """A readable and writable node that READ and WRITE name (the value read is written back)."""
    return pick(ctx, lambda d: RW in d.permission, what="readable and writable data node")


class _Paths(NamedTuple):
    """A data node, its access and the group above that (or `/`)."""

    node: str
    access: str
    above: str


def _paths(ctx: Context) -> _Paths:
    access = ctx.access(where=lambda a: bool(a.data))
    return _Paths(access.data[0].path, access.path, parent_of(access.path))


async def _held(ctx: Context, path: str) -> tuple[ControlProbe, ControlProbe]:
    """Two sessions, once no session holds anything: the first (the holder) holding `path`."""
    holder, other = await sessions(ctx, 2)
    await acquire(ctx, holder, path)
    return holder, other


async def _ask(probe: ControlProbe, method: str, path: str) -> Response:
    return await probe.request(method, format_target(path))


async def _same_value(ctx: Context, probe: ControlProbe, named: Named) -> Response:
    """WRITE of the value the node holds: allowed or refused, it changes nothing."""
    return await write(probe, named, await read(ctx, probe, named))


async def _overlapping(ctx: Context, held: str, *asked: str) -> None:
    """While one session holds `held`, another's ACQUIRE of each path of `asked`, all
    overlapping it, is answered 471."""
    _, other = await _held(ctx, held)
    for path in dict.fromkeys(asked):  # the group above an access may be `/` itself
        ctx.expect_status(await _ask(other, "ACQUIRE", path), 471)


async def _bye(probe: ControlProbe) -> None:
    """BYE as a precondition: inconclusive if refused (the rctp/session cases check it)."""
    bye = await probe.request("BYE", STAR)
    if bye.status != 200:
        raise Inconclusive(f"BYE was answered {bye.status} {bye.reason}")


# -- the privilege and WRITE (R-RCTP-34) -------------------------------------------------------


@case(
    "rctp/priv/write-not-acquired",
    "WRITE of a node no session holds is answered 470",
    ["R-RCTP-34"],
    serial=True,
)
async def write_not_acquired(ctx: Context) -> None:
    named = _writable(ctx)
    (probe,) = await sessions(ctx, 1)
    ctx.expect_status(await _same_value(ctx, probe, named), 470)


@case(
    "rctp/priv/acquire-write",
    "ACQUIRE of a writable node is answered 200, and a WRITE of it then 200",
    ["R-RCTP-33", "R-RCTP-34"],
    serial=True,
)
async def acquire_write(ctx: Context) -> None:
    named = _writable(ctx)
    (probe,) = await sessions(ctx, 1)
    ctx.expect_status(await _ask(probe, "ACQUIRE", named.path), 200)
    ctx.expect_status(await _same_value(ctx, probe, named), 200, "R-RCTP-34")


@case(
    "rctp/priv/acquire-above-write",
    "ACQUIRE of the group above a node lets the session WRITE the node",
    ["R-RCTP-34"],
    serial=True,
)
async def acquire_above_write(ctx: Context) -> None:
    named = _writable(ctx)
    (probe,) = await sessions(ctx, 1)
    await acquire(ctx, probe, parent_of(parent_of(named.node.path)))
    ctx.expect_status(await _same_value(ctx, probe, named), 200)


@case(
    "rctp/priv/write-held-by-other",
    "WRITE of a node another session holds is answered 471",
    ["R-RCTP-34"],
    serial=True,
)
async def write_held_by_other(ctx: Context) -> None:
    named = _writable(ctx)
    _, other = await _held(ctx, named.path)
    ctx.expect_status(await _same_value(ctx, other, named), 471)


@case(
    "rctp/priv/read-not-acquired",
    "READ needs no privilege: it is answered 200 while another session holds the whole tree",
    ["R-RCTP-34"],
    serial=True,
)
async def read_not_acquired(ctx: Context) -> None:
    named = pick(ctx, lambda d: Permission.READ in d.permission)
    _, reader = await _held(ctx, ROOT)
    answer = await reader.request("READ", named.target, named.fields())
    ctx.expect_status(answer, 200)


# -- ACQUIRE (R-RCTP-33, R-RCTP-37) ------------------------------------------------------------


@case(
    "rctp/priv/acquire-busy",
    "ACQUIRE of a path another session holds is answered 471",
    ["R-RCTP-33"],
    serial=True,
)
async def acquire_busy(ctx: Context) -> None:
    paths = _paths(ctx)
    await _overlapping(ctx, paths.access, paths.access)


@case(
    "rctp/priv/acquire-below-held",
    "ACQUIRE of a node below a path another session holds is answered 471",
    ["R-RCTP-33", "R-RCTP-37"],
    serial=True,
)
async def acquire_below_held(ctx: Context) -> None:
    paths = _paths(ctx)
    await _overlapping(ctx, paths.above, paths.access, paths.node)


@case(
    "rctp/priv/acquire-above-held",
    "ACQUIRE of the access, a group or the whole tree above a node another session holds is 471",
    ["R-RCTP-33", "R-RCTP-37"],
    serial=True,
)
async def acquire_above_held(ctx: Context) -> None:
    paths = _paths(ctx)
    await _overlapping(ctx, paths.node, paths.access, paths.above, ROOT)


@case(
    "rctp/priv/acquire-disjoint",
    "ACQUIRE of a path that does not overlap another session's is answered 200",
    ["R-RCTP-33"],
    serial=True,
)
async def acquire_disjoint(ctx: Context) -> None:
    accesses = [a.path for a in ctx.robot.access_nodes()]
    if len(accesses) < 2:
        raise NotApplicable("the robot has fewer than two access nodes")
    first, second = accesses[:2]
    _, other = await _held(ctx, first)
    ctx.expect_status(await _ask(other, "ACQUIRE", second), 200)


@case(
    "rctp/priv/acquire-again",
    "ACQUIRE of a path the session holds, or of a node below it, is 200 and changes nothing",
    ["R-RCTP-33"],
    serial=True,
)
async def acquire_again(ctx: Context) -> None:
    _, access, above = _paths(ctx)
    holder, other = await _held(ctx, above)
    ctx.expect_status(await _ask(holder, "ACQUIRE", above), 200)
    ctx.expect_status(await _ask(holder, "ACQUIRE", access), 200)
    # Changed nothing: one RELEASE of the path acquired gives back everything below it.
    ctx.expect_status(await _ask(holder, "RELEASE", above), 200)
    ctx.expect_status(await _ask(other, "ACQUIRE", access), 200)


@case(
    "rctp/priv/acquire-missing",
    "ACQUIRE of a path that names no node is answered 404",
    ["R-RCTP-26"],
)
async def acquire_missing(ctx: Context) -> None:
    probe = await ctx.session()
    ctx.expect_status(await _ask(probe, "ACQUIRE", missing_path(ctx)), 404)


@case(
    "rctp/priv/acquire-session",
    "ACQUIRE of * is answered 405 with Allow: RELEASE, BYE",
    ["R-RCTP-26"],
    serial=True,
)
async def acquire_session(ctx: Context) -> None:
    (probe,) = await sessions(ctx, 1)
    check_allow(ctx, await probe.request("ACQUIRE", STAR), STAR)


@case(
    "rctp/priv/acquire-race",
    "Two sessions asking for the same or overlapping paths at once: exactly one is granted",
    ["R-RCTP-37"],
    serial=True,
)
async def acquire_race(ctx: Context) -> None:
    _, access, above = _paths(ctx)
    first, second = await sessions(ctx, 2)
    pairs = [(access, access), (above, access), (access, above), (above, above)]
    for index, (one, two) in enumerate(pairs[:_RACES]):
        a, b = (first, second) if index % 2 == 0 else (second, first)
        await a.send(a.request_bytes("ACQUIRE", format_target(one)))
        await b.send(b.request_bytes("ACQUIRE", format_target(two)))
        answers = await asyncio.gather(a.response(), b.response())
        statuses = sorted(r.status for r in answers)
        ctx.expect(
            statuses == [200, 471],
            f"ACQUIRE {one} and {two} at once: one 200, one 471",
            f"{answers[0].status} and {answers[1].status}",
        )
        winner, path = (a, one) if answers[0].status == 200 else (b, two)
        ctx.expect_status(await _ask(winner, "RELEASE", path), 200, "R-RCTP-35")


# -- RELEASE (R-RCTP-35) -----------------------------------------------------------------------


@case(
    "rctp/priv/release-not-acquired",
    "RELEASE of a path the session did not acquire is answered 470",
    ["R-RCTP-35"],
    serial=True,
)
async def release_not_acquired(ctx: Context) -> None:
    access = _paths(ctx).access
    (probe,) = await sessions(ctx, 1)
    ctx.expect_status(await _ask(probe, "RELEASE", access), 470)


@case(
    "rctp/priv/release-taken-in",
    "After ACQUIRE of a node and then of its access, which takes the node in, RELEASE of the node"
    " is 470 and of the access 200, which gives back both",
    ["R-RCTP-35", "R-RCTP-33"],
    serial=True,
)
async def release_taken_in(ctx: Context) -> None:
    # D-RCTP-16: acquiring above held paths takes them in, so the session holds the new path
    # alone, and RELEASE names exactly a path held: one no later ACQUIRE took in.
    paths = _paths(ctx)
    holder, other = await sessions(ctx, 2)
    await acquire(ctx, holder, paths.node)
    await acquire(ctx, holder, paths.access)
    ctx.expect_status(await _ask(holder, "RELEASE", paths.node), 470, what=f"RELEASE {paths.node}")
    ctx.expect_status(await _ask(other, "ACQUIRE", paths.node), 471, "R-RCTP-33")
    ctx.expect_status(await _ask(holder, "RELEASE", paths.access), 200)
    ctx.expect_status(await _ask(other, "ACQUIRE", paths.node), 200, "R-RCTP-33")


@case(
    "rctp/priv/release-other",
    "RELEASE of a path another session holds is answered 470 and leaves it held",
    ["R-RCTP-35", "R-RCTP-33"],
    serial=True,
)
async def release_other(ctx: Context) -> None:
    access = _paths(ctx).access
    _, other = await _held(ctx, access)
    ctx.expect_status(await _ask(other, "RELEASE", access), 470)
    ctx.expect_status(await _ask(other, "ACQUIRE", access), 471, "R-RCTP-33")


@case(
    "rctp/priv/release",
    "RELEASE of a path acquired is 200; then another session can ACQUIRE it and WRITE is 470",
    ["R-RCTP-35", "R-RCTP-34"],
    serial=True,
)
async def release(ctx: Context) -> None:
    named = _writable(ctx)
    holder, other = await _held(ctx, named.path)
    ctx.expect_status(await _ask(holder, "RELEASE", named.path), 200)
    ctx.expect_status(await _same_value(ctx, holder, named), 470, "R-RCTP-34")
    ctx.expect_status(await _ask(other, "ACQUIRE", named.path), 200, "R-RCTP-33")


@case(
    "rctp/priv/release-all",
    "RELEASE of * gives back every path the session holds",
    ["R-RCTP-35", "R-RCTP-33"],
    serial=True,
)
async def release_all(ctx: Context) -> None:
    accesses = [a.path for a in ctx.robot.access_nodes()][:2]
    holder, other = await sessions(ctx, 2)
    for path in accesses:
        await acquire(ctx, holder, path)
    ctx.expect_status(await holder.request("RELEASE", STAR), 200)
    for path in accesses:
        ctx.expect_status(await _ask(other, "ACQUIRE", path), 200, "R-RCTP-33")


@case(
    "rctp/priv/release-writing-stream",
    "RELEASE while a stream below is set up for writing is 455; after its STOP, 200",
    ["R-RCTP-35"],
    serial=True,
)
async def release_writing_stream(ctx: Context) -> None:
    def writes(access: AccessNode) -> bool:
        return bool(access.writable())

    access = ctx.access(AccessType.STREAM, Permission.WRITE, writes)
    port = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)  # where the server may send
    ctx.on_close(port.close)
    port.bind(("127.0.0.1", 0))
    (probe,) = await sessions(ctx, 1)
    await acquire(ctx, probe, access.path)
    transport = Transport(client_port=port.getsockname()[1], mode="write")
    answer = await probe.request(
        "SETUP", format_target(access.path), [("Transport", str(transport))]
    )
    if answer.status != 200:
        raise Inconclusive(f"SETUP for writing was answered {answer.status} {answer.reason}")
    ctx.expect_status(await _ask(probe, "RELEASE", access.path), 455)
    ctx.expect_status(await _ask(probe, "RELEASE", STAR), 455)
    stopped = await _ask(probe, "STOP", access.path)
    if stopped.status != 200:
        raise Inconclusive(f"STOP was answered {stopped.status} {stopped.reason}")
    ctx.expect_status(await _ask(probe, "RELEASE", access.path), 200)


# -- the end of a session (R-RCTP-36) ----------------------------------------------------------


@case(
    "rctp/priv/bye-releases",
    "Once a session's BYE is answered, another session can ACQUIRE what it held",
    ["R-RCTP-36"],
    serial=True,
)
async def bye_releases(ctx: Context) -> None:
    access = _paths(ctx).access
    holder, other = await _held(ctx, access)
    await _bye(holder)
    ctx.expect_status(await _ask(other, "ACQUIRE", access), 200)


@case(
    "rctp/priv/close-releases",
    "When a session's connection closes, another session can ACQUIRE what it held",
    ["R-RCTP-36"],
    serial=True,
)
async def close_releases(ctx: Context) -> None:
    access = _paths(ctx).access
    holder, other = await _held(ctx, access)
    holder.close()
    # The server learns of the close when it reads it: ask again for a moment.
    deadline = asyncio.get_running_loop().time() + _CLOSE_WAIT * ctx.scale
    while True:
        answer = await _ask(other, "ACQUIRE", access)
        if answer.status != 471 or asyncio.get_running_loop().time() > deadline:
            break
        await asyncio.sleep(_POLL)
    ctx.expect_status(answer, 200)


@case(
    "rctp/priv/write-after-bye",
    "A WRITE by another session after the holder's BYE is 470, not 471: nothing is held",
    ["R-RCTP-36", "R-RCTP-34"],
    serial=True,
)
async def write_after_bye(ctx: Context) -> None:
    named = _writable(ctx)
    holder, other = await _held(ctx, named.path)
    await _bye(holder)
    ctx.expect_status(await _same_value(ctx, other, named), 470)
