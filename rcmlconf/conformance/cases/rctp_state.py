"""rctp/state: every method in every session state and every stream method in every stream state,
which error wins when several apply, and what each kind of target allows (specs/rctp-2.0.md
D-RCTP-13, D-RCTP-14, D-RCTP-25, D-RCTP-26, R-RCTP-17, R-RCTP-20, R-RCTP-26)."""

from __future__ import annotations

from collections.abc import Sequence

from rcmlconf.conformance.context import Context, expect_answer
from rcmlconf.conformance.picks import STRANGER, first, read_target, unknown_target
from rcmlconf.conformance.probes.control import ControlProbe, Fields
from rcmlconf.conformance.registry import case
from rcmlconf.conformance.verdicts import Failed, Inconclusive, NotApplicable
from rcmlconf.errors import ValueTextError
from rcmlconf.rcml.model import AccessNode, AccessType, DataNode, GroupNode, Permission
from rcmlconf.rctp.fields import format_nodes, parse_session
from rcmlconf.rctp.messages import VERSION, Request, Response
from rcmlconf.rctp.targets import format_target

#: D-RCTP-26, each row in the table's order (the order of `Allow`).
SESSION_ROW = ("RELEASE", "BYE")
TREE_ROW = ("ACQUIRE", "RELEASE")
NORMAL_DATA_ROW = ("ACQUIRE", "RELEASE", "READ", "WRITE")
EVENT_ROW = ("ACQUIRE", "RELEASE", "READ", "WRITE", "SETUP", "GO", "PAUSE", "STOP")
STREAM_ROW = ("ACQUIRE", "RELEASE", "SETUP", "GO", "PAUSE", "STOP")
INNER_DATA_ROW = ("ACQUIRE", "RELEASE")


@case(
    "rctp/state/idle-methods",
    "Before CONNECT every other method, on a target that would take it, is answered 454",
    ["R-RCTP-17"],
)
async def idle_methods(ctx: Context) -> None:
    probe = await ctx.control()
    for method, target, fields, body in _every_method(ctx, connect=False):
        answer = await probe.request(method, target, fields, body)
        expect_answer(ctx, answer, 454, f"{method} {target} before CONNECT")
    expect_answer(ctx, await probe.connect(ctx.target.site_path), 200, "CONNECT afterwards")


@case(
    "rctp/state/open-methods",
    "In an open session every method passes the session and state checks: 200, or the node's 404",
    ["R-RCTP-20", "R-RCTP-17"],
)
async def open_methods(ctx: Context) -> None:
    probe = await ctx.session()
    missing = unknown_target(ctx)
    event = format_target(_event(ctx).path)
    steps: list[tuple[str, str, Fields, bytes, int]] = [
        ("CONNECT", ctx.target.site_path, [], b"", 200),
        ("ACQUIRE", missing, [], b"", 404),
        ("RELEASE", "*", [], b"", 200),
        ("READ", read_target(ctx), [], b"", 200),
        ("WRITE", missing, [], b"\0", 404),
        ("SETUP", event, [], b"", 200),
        ("GO", event, [], b"", 200),
        ("PAUSE", event, [], b"", 200),
        ("STOP", event, [], b"", 200),
        ("BYE", "*", [], b"", 200),
    ]
    for method, target, fields, body, status in steps:
        answer = await probe.request(method, target, fields, body)
        expect_answer(ctx, answer, status, f"{method} {target} in open", "R-RCTP-20")


@case(
    "rctp/state/closing-methods",
    "While the server's BYE waits for its answer every method is answered 455, in order",
    ["R-RCTP-20", "R-RCTP-5"],
    timeout=10.0,
    waits_session=True,
)
async def closing_methods(ctx: Context) -> None:
    probe = await ctx.control()
    timeout = ctx.waited_session(_timeout(await probe.connect(ctx.target.site_path)))
    try:
        bye = await probe.message(timeout + 1.5 * ctx.scale)
    except Failed as failed:
        if failed.requirement != "R-RCTP-5":
            raise
        bye = None
    if not isinstance(bye, Request) or bye.method != "BYE":
        # rctp/session/timeout-bye fails such a server
        raise Inconclusive("no BYE once the session timeout passed")
    requests = _every_method(ctx)
    await probe.send(
        b"".join(
            probe.request_bytes(method, target, f, body) for method, target, f, body in requests
        )
    )
    for method, target, _, _ in requests:
        # Each answer's CSeq is its request's, in order (R-RCTP-5), as the probe matches them.
        answer = await probe.response(cseq_rule="R-RCTP-5")
        expect_answer(ctx, answer, 455, f"{method} {target} while closing")
    await probe.answer(bye)


@case(
    "rctp/state/closed-nothing-sent",
    "After the client's BYE is answered, a request gets no answer: nothing is sent in closed",
    ["R-RCTP-23"],
)
async def closed_nothing_sent(ctx: Context) -> None:
    probe = await ctx.session()
    ctx.expect_status(await probe.request("BYE", "*"), 200)
    normal = read_target(ctx)
    await probe.send(probe.request_bytes("READ", normal))
    try:
        found = await probe.message(ctx.scale)
    except Failed as failed:
        if failed.requirement != "R-RCTP-5":
            raise
        return  # silent: nothing sent
    if isinstance(found, Response):
        ctx.expect(False, "no answer once the session is closed", f"{found.status} {found.reason}")
    ctx.expect(found is None, "nothing sent once the session is closed", f"{found!r}")


@case(
    "rctp/state/pipelined-after-bye",
    "An ACQUIRE pipelined behind the client's BYE is neither answered nor granted",
    ["R-RCTP-36", "R-RCTP-23"],
    serial=True,
)
async def pipelined_after_bye(ctx: Context) -> None:
    path = format_target(ctx.access().path)
    probe = await ctx.session()
    await probe.send(probe.request_bytes("BYE", "*") + probe.request_bytes("ACQUIRE", path))
    ctx.expect_status(await probe.response(), 200, "R-RCTP-23")
    try:
        found = await probe.message(ctx.scale)
    except Failed as failed:
        if failed.requirement != "R-RCTP-5":
            raise
        found = None  # silent: nothing sent
    shown = f"{found.status} {found.reason}" if isinstance(found, Response) else f"{found!r}"
    ctx.expect(found is None, "nothing after the answer to BYE", shown, "R-RCTP-23")
    other = await ctx.session()
    answer = await other.request("ACQUIRE", path)
    ctx.expect_status(answer, 200, "R-RCTP-36")
    await other.request("RELEASE", "*")


@case(
    "rctp/state/stream-init",
    "GO, PAUSE and STOP of an event access never set up are answered 455; SETUP takes it to ready",
    ["R-RCTP-20"],
)
async def stream_init(ctx: Context) -> None:
    probe = await ctx.session()
    await _walk(
        ctx,
        probe,
        _event(ctx),
        [("GO", 455), ("PAUSE", 455), ("STOP", 455), ("SETUP", 200), ("PAUSE", 200)],
    )


@case(
    "rctp/state/stream-ready",
    "In ready SETUP and PAUSE stay in ready, STOP goes to init and GO to playing, each 200",
    ["R-RCTP-20"],
)
async def stream_ready(ctx: Context) -> None:
    probe = await ctx.session()
    steps = [
        ("SETUP", 200),
        ("SETUP", 200),
        ("PAUSE", 200),
        ("STOP", 200),
        ("GO", 455),  # init again
        ("SETUP", 200),
        ("GO", 200),
        ("SETUP", 455),  # playing
    ]
    await _walk(ctx, probe, _event(ctx), steps)


@case(
    "rctp/state/stream-playing",
    "In playing SETUP is answered 455, GO stays, PAUSE goes to ready and STOP to init, each 200",
    ["R-RCTP-20"],
)
async def stream_playing(ctx: Context) -> None:
    probe = await ctx.session()
    steps = [
        ("SETUP", 200),
        ("GO", 200),
        ("SETUP", 455),
        ("GO", 200),
        ("SETUP", 455),  # still playing
        ("PAUSE", 200),
        ("SETUP", 200),  # ready
        ("GO", 200),
        ("STOP", 200),
        ("PAUSE", 455),  # init
    ]
    await _walk(ctx, probe, _event(ctx), steps)


@case(
    "rctp/state/stream-state-per-access",
    "Setting up and playing one access leaves another in init: its GO and PAUSE are answered 455",
    ["R-RCTP-20"],
)
async def stream_state_per_access(ctx: Context) -> None:
    probe = await ctx.session()
    event = _event(ctx)
    other = ctx.access(where=lambda a: a.type is not AccessType.NORMAL and a.path != event.path)
    await _walk(ctx, probe, event, [("SETUP", 200), ("GO", 200)])
    await _walk(ctx, probe, other, [("GO", 455), ("PAUSE", 455)])
    await _walk(ctx, probe, event, [("PAUSE", 200)])


@case(
    "rctp/state/stream-state-per-session",
    "An access playing in one session is in init in another: its GO and STOP there are 455",
    ["R-RCTP-20"],
)
async def stream_state_per_session(ctx: Context) -> None:
    event = _event(ctx)
    first = await ctx.session()
    await _walk(ctx, first, event, [("SETUP", 200), ("GO", 200)])
    second = await ctx.session()
    await _walk(ctx, second, event, [("GO", 455), ("STOP", 455)])
    await _walk(ctx, first, event, [("STOP", 200)])


@case(
    "rctp/state/order-before-session",
    "Before CONNECT, method (501), version (505), CSeq and repeated fields (400) and target (400) "
    "errors win over 454",
    ["R-RCTP-17", "R-RCTP-9", "R-RCTP-10", "R-RCTP-11", "R-RCTP-15"],
)
async def order_before_session(ctx: Context) -> None:
    probe = await ctx.control()
    normal = read_target(ctx)
    # A request without CSeq does not count: the numbering goes on from the last readable one.
    steps: list[tuple[bytes, int, str, str]] = [
        (b"FROBNICATE * RCTP/3.0\r\n\r\n", 501, "R-RCTP-9", "before the version and CSeq"),
        (f"READ {normal} RCTP/3.0\r\n\r\n".encode(), 505, "R-RCTP-10", "before CSeq"),
        (f"READ {normal} {VERSION}\r\nCSeq: one\r\n\r\n".encode(), 400, "R-RCTP-11", ""),
        (
            f"READ {normal} {VERSION}\r\nCSeq: 1\r\nSession: {STRANGER}\r\n"
            f"Session: {STRANGER}\r\n\r\n".encode(),
            400,
            "R-RCTP-11",
            "Session twice",
        ),
        (f"READ /1abc {VERSION}\r\nCSeq: 2\r\n\r\n".encode(), 400, "R-RCTP-15", "a bad target"),
        (f"READ {normal} {VERSION}\r\nCSeq: 3\r\n\r\n".encode(), 454, "R-RCTP-17", "no session"),
    ]
    for data, status, requirement, note in steps:
        await probe.send(data)
        line = data.split(b"\r\n")[0].decode()
        what = f"{line} before CONNECT" + (f" ({note})" if note else "")
        expect_answer(ctx, await probe.response(), status, what, requirement)


@case(
    "rctp/state/order-state-before-node",
    "GO, PAUSE and STOP of a path that names no node, never set up, are answered 455, not 404",
    ["R-RCTP-20", "R-RCTP-26"],
)
async def order_state_before_node(ctx: Context) -> None:
    probe = await ctx.session()
    missing = unknown_target(ctx)
    for method, status, requirement in (
        ("GO", 455, "R-RCTP-20"),
        ("PAUSE", 455, "R-RCTP-20"),
        ("STOP", 455, "R-RCTP-20"),
        ("SETUP", 404, "R-RCTP-26"),  # init takes SETUP: the node check decides
    ):
        answer = await probe.request(method, missing)
        expect_answer(ctx, answer, status, f"{method} {missing}", requirement)


@case(
    "rctp/state/order-session-before-state",
    "GO of an access in init, naming another session or none, is answered 454, not 455",
    ["R-RCTP-19", "R-RCTP-20"],
)
async def order_session_before_state(ctx: Context) -> None:
    probe = await ctx.session()
    event = format_target(_event(ctx).path)
    answer = await probe.request("GO", event, [("Session", STRANGER)])
    expect_answer(ctx, answer, 454, f"GO {event} with Session: {STRANGER}", "R-RCTP-19")
    probe.cseq += 1
    await probe.send(f"GO {event} {VERSION}\r\nCSeq: {probe.cseq}\r\n\r\n".encode())
    expect_answer(ctx, await probe.response(), 454, f"GO {event} without Session", "R-RCTP-19")
    expect_answer(ctx, await probe.request("GO", event), 455, f"GO {event}", "R-RCTP-20")


@case(
    "rctp/state/order-after-session",
    "A WRITE failing several checks gets the first: node (404, 405), then permission (403), then "
    "privilege (470) before the body (415)",
    ["R-RCTP-26", "R-RCTP-27", "R-RCTP-34"],
)
async def order_after_session(ctx: Context) -> None:
    probe = await ctx.session()
    text = [("Content-Type", "text/plain; charset=utf-8")]
    steps: list[tuple[str, Fields, tuple[int, ...], str]] = [
        (unknown_target(ctx), text, (404,), "R-RCTP-26"),
        ("/", text, (405,), "R-RCTP-26"),
    ]
    refused = _unwritable(ctx)
    if refused is not None:
        steps.append((refused[0], [*refused[1], *text], (403,), "R-RCTP-27"))
    writable = _writable(ctx)
    if writable is not None:
        # 471 if another session happens to hold it: the privilege check all the same
        steps.append((writable[0], [*writable[1], *text], (470, 471), "R-RCTP-34"))
    for target, fields, statuses, requirement in steps:
        answer = await probe.request("WRITE", target, fields, b"rcmlconf")
        what = f"WRITE {target} with a text/plain body, not holding it"
        expect_answer(ctx, answer, statuses, what, requirement)


@case(
    "rctp/state/allow-session-and-tree",
    "A method * or /, a group or a normal access does not take is answered 405 with Allow in "
    "D-RCTP-26's order",
    ["R-RCTP-26"],
)
async def allow_session_and_tree(ctx: Context) -> None:
    probe = await ctx.session()
    steps = [("READ", "*", SESSION_ROW), ("ACQUIRE", "*", SESSION_ROW), ("READ", "/", TREE_ROW)]
    steps.append(("SETUP", "/", TREE_ROW))
    group = next((n for n in ctx.robot.nodes.values() if isinstance(n, GroupNode)), None)
    if group is not None:
        steps.append(("READ", format_target(group.path), TREE_ROW))
    normal = first(ctx, AccessType.NORMAL)
    if normal is not None:
        steps.append(("SETUP", format_target(normal.path), TREE_ROW))
    for method, target, row in steps:
        await _not_allowed(ctx, probe, method, target, row)


@case(
    "rctp/state/allow-data-nodes",
    "A method a data node does not take is answered 405 with Allow: four methods for a normal "
    "access's, two for others'",
    ["R-RCTP-26", "R-RCTP-31"],
)
async def allow_data_nodes(ctx: Context) -> None:
    probe = await ctx.session()
    checked = 0
    normal = _inner_data(ctx, AccessType.NORMAL)
    if normal is not None:
        await _not_allowed(ctx, probe, "SETUP", format_target(normal.path), NORMAL_DATA_ROW)
        await _not_allowed(ctx, probe, "BYE", format_target(normal.path), NORMAL_DATA_ROW)
        checked += 1
    for kind in (AccessType.EVENT, AccessType.STREAM):
        inner = _inner_data(ctx, kind)
        if inner is not None:
            await _not_allowed(ctx, probe, "READ", format_target(inner.path), INNER_DATA_ROW)
            await _not_allowed(ctx, probe, "SETUP", format_target(inner.path), INNER_DATA_ROW)
            checked += 1
    if not checked:
        raise NotApplicable("the robot has no data node")


@case(
    "rctp/state/allow-accesses",
    "BYE of an event access and READ or WRITE of a stream access are answered 405 with their "
    "rows of D-RCTP-26 as Allow",
    ["R-RCTP-26", "R-RCTP-31"],
)
async def allow_accesses(ctx: Context) -> None:
    probe = await ctx.session()
    event = first(ctx, AccessType.EVENT)
    stream = first(ctx, AccessType.STREAM)
    if event is None and stream is None:
        raise NotApplicable("the robot has no event or stream access")
    if event is not None:
        await _not_allowed(ctx, probe, "BYE", format_target(event.path), EVENT_ROW)
    if stream is not None:
        await _not_allowed(ctx, probe, "READ", format_target(stream.path), STREAM_ROW)
        await _not_allowed(ctx, probe, "WRITE", format_target(stream.path), STREAM_ROW, b"\0")


# -- helpers -----------------------------------------------------------------------------------


def _every_method(ctx: Context, *, connect: bool = True) -> list[tuple[str, str, Fields, bytes]]:
    """Each of the ten methods on a target that takes it (a readable event access for the stream
    methods, a readable normal data node for READ), CONNECT first, BYE last."""
    event = _event(ctx)
    target = format_target(event.path)
    writable = event.writable()
    write: tuple[str, str, Fields, bytes] = (
        ("WRITE", target, [("Nodes", format_nodes([writable[0].name]))], b"\0")
        if writable
        else ("WRITE", unknown_target(ctx), [], b"\0")
    )
    methods: list[tuple[str, str, Fields, bytes]] = [
        ("CONNECT", ctx.target.site_path, [], b""),
        ("ACQUIRE", target, [], b""),
        ("RELEASE", "*", [], b""),
        ("READ", read_target(ctx), [], b""),
        write,
        ("SETUP", target, [], b""),
        ("GO", target, [], b""),
        ("PAUSE", target, [], b""),
        ("STOP", target, [], b""),
        ("BYE", "*", [], b""),
    ]
    return methods if connect else methods[1:]


async def _walk(
    ctx: Context, probe: ControlProbe, access: AccessNode, steps: Sequence[tuple[str, int]]
) -> None:
    """Each method of `steps` on `access`, answered with its status (D-RCTP-14). SETUP carries no
    Transport: `access` is an event access, unless `steps` holds no SETUP."""
    target = format_target(access.path)
    for index, (method, status) in enumerate(steps, start=1):
        answer = await probe.request(method, target)
        what = f"step {index} of {len(steps)}: {method} {target}"
        expect_answer(ctx, answer, status, what, "R-RCTP-20")


async def _not_allowed(
    ctx: Context,
    probe: ControlProbe,
    method: str,
    target: str,
    row: tuple[str, ...],
    body: bytes = b"",
) -> None:
    """`method` of `target` is answered 405 with `row` as Allow (R-RCTP-26)."""
    answer = await probe.request(method, target, (), body)
    expect_answer(ctx, answer, 405, f"{method} {target}", "R-RCTP-26")
    given = answer.headers.get("Allow")
    listed = tuple(m.strip(" \t") for m in given.split(",")) if given is not None else ()
    ctx.expect(
        listed == row,
        f"Allow: {', '.join(row)}",
        f"Allow: {given}" if given is not None else "no Allow",
        "R-RCTP-26",
    )


def _timeout(answer: Response) -> int:
    """The session timeout CONNECT's answer announces; inconclusive when there is none (the
    rctp/session cases check it)."""
    given = answer.headers.get("Session") or ""
    try:  # `timeout` in any letter case (D-RCTP-30)
        timeout = parse_session(given).timeout if answer.status == 200 else None
    except ValueTextError:
        timeout = None
    if timeout is None:
        raise Inconclusive(f"CONNECT was answered {answer.status} with Session: {given}")
    return timeout


def _event(ctx: Context) -> AccessNode:
    return ctx.access(AccessType.EVENT, Permission.READ)


def _inner_data(ctx: Context, kind: AccessType) -> DataNode | None:
    """A data node of an access of `kind`."""
    for access in ctx.robot.access_nodes():
        if access.type is kind and access.data:
            return access.data[0]
    return None


def _writable(ctx: Context) -> tuple[str, Fields] | None:
    """A WRITE target whose nodes the permission lets be written, or None."""
    for access in ctx.robot.access_nodes():
        writable = access.writable()
        if access.type is AccessType.NORMAL and writable:
            return format_target(writable[0].path), []
        if access.type is AccessType.EVENT and writable:
            return format_target(access.path), [("Nodes", format_nodes([writable[0].name]))]
    return None


def _unwritable(ctx: Context) -> tuple[str, Fields] | None:
    """A WRITE target whose node the permission does not let be written (403), or None."""
    for access in ctx.robot.access_nodes():
        for data in access.data:
            if Permission.WRITE in data.permission:
                continue
            if access.type is AccessType.NORMAL:
                return format_target(data.path), []
            if access.type is AccessType.EVENT:
                return format_target(access.path), [("Nodes", format_nodes([data.name]))]
    return None
