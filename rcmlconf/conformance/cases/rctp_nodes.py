"""rctp/node: READ and WRITE of data nodes and event accesses, and what a server answers for a
target that cannot be read or written (specs/rctp-2.0.md §3 D-RCTP-25, D-RCTP-26, §5 D-RCTP-17,
R-RCTP-26 to R-RCTP-31).

The helpers at the top (valid and invalid values of a node, checked bodies, READ, WRITE and the
privilege as preconditions) are shared with `rctp_privilege` and `rctp_events`; the nodes are
picked from the robot's RCML (`conformance.picks`). A WRITE needs the privilege before its body
is judged (D-RCTP-25), and the privilege is the whole server's: every case here that ACQUIREs
runs alone (`serial`).
"""

from __future__ import annotations

import asyncio
import contextlib
import math
import struct
from collections.abc import Callable, Iterator, Mapping, Sequence

from rcmlconf.conformance.context import Context, expect_answer
from rcmlconf.conformance.picks import (
    MISSING,
    RW,
    Named,
    event_access,
    first,
    missing_path,
    pick,
    writable,
)
from rcmlconf.conformance.probes.control import ControlProbe, Fields
from rcmlconf.conformance.registry import case
from rcmlconf.conformance.verdicts import Failed, Inconclusive, NotApplicable
from rcmlconf.errors import ProtocolError, ValueTextError
from rcmlconf.rcml.model import AccessNode, AccessType, DataNode, GroupNode, Permission
from rcmlconf.rctp.allowed import TargetKind, target_kind
from rcmlconf.rctp.bodies import ValuesCodec
from rcmlconf.rctp.fields import format_nodes, parse_nodes, same_token
from rcmlconf.rctp.messages import TEXT_TYPE, VALUES_TYPE, Message, Response
from rcmlconf.rctp.targets import ROOT, format_target
from rcmlconf.values import Kind, Scalar, Value

_FLOAT32 = struct.Struct(">f")
#: Distinct values `values_for` offers at most.
_VARIETY = 16
#: Seconds a serial case waits for the privileges of the sessions before it to go, and how
#: often it asks meanwhile (`unheld`).
_FREE_WAIT = 1.0
_POLL = 0.02
#: D-RCTP-26's table, written out again rather than taken from `rctp.allowed` (which the
#: reference server answers from): a wrong row there must fail these cases, not agree with them.
ALLOW: dict[TargetKind, tuple[str, ...]] = {
    TargetKind.SESSION: ("RELEASE", "BYE"),
    TargetKind.TREE: ("ACQUIRE", "RELEASE"),
    TargetKind.NORMAL_DATA: ("ACQUIRE", "RELEASE", "READ", "WRITE"),
    TargetKind.EVENT_ACCESS: (
        "ACQUIRE",
        "RELEASE",
        "READ",
        "WRITE",
        "SETUP",
        "GO",
        "PAUSE",
        "STOP",
    ),
    TargetKind.STREAM_ACCESS: ("ACQUIRE", "RELEASE", "SETUP", "GO", "PAUSE", "STOP"),
    TargetKind.INNER_DATA: ("ACQUIRE", "RELEASE"),
}

# -- what a READ or WRITE names ----------------------------------------------------------------


def percent_encoded(path: str) -> str:
    """`path` with the first character of every segment percent-encoded (D-RCTP-7)."""
    segments = []
    for segment in format_target(path)[1:].split("/"):
        if not segment.startswith("%"):
            segment = "".join(f"%{b:02X}" for b in segment[0].encode()) + segment[1:]
        segments.append(segment)
    return "/" + "/".join(segments)


# -- values ------------------------------------------------------------------------------------


def _bounds(node: DataNode) -> tuple[float, float]:
    base = node.type.base
    low: float = -math.inf if node.minimum is None else node.minimum
    high: float = math.inf if node.maximum is None else node.maximum
    if base.kind is Kind.INTEGER:
        return max(low, base.low), min(high, base.high)
    return low, high


def _typed(node: DataNode, number: float) -> float:
    """A float as the node's float type holds it."""
    if node.type.base.name == "float32":
        try:
            return float(_FLOAT32.unpack(_FLOAT32.pack(number))[0])
        except OverflowError:
            return math.copysign(math.inf, number)
    return number


def _scalars(node: DataNode) -> Iterator[Scalar]:
    """Valid items of the node's type and range, varied, maybe repeated."""
    kind = node.type.base.kind
    if kind is Kind.BOOL:
        yield from (False, True)
    elif kind is Kind.STRING:
        yield from ("", *(chr(ord("a") + i) for i in range(_VARIETY)))
    elif kind is Kind.BYTES:
        yield from (b"", *(bytes([i]) for i in range(_VARIETY)))
    elif kind is Kind.INTEGER:
        low, high = _bounds(node)
        centre = int(min(max(0, low), high))
        for step in range(_VARIETY):
            for item in (centre + step, centre - step):
                if low <= item <= high:
                    yield item
    else:
        low, high = _bounds(node)
        if math.isfinite(low) and math.isfinite(high):
            numbers = [low + (high - low) * i / _VARIETY for i in range(_VARIETY + 1)]
        elif math.isfinite(low):
            numbers = [low + i / 4 for i in range(_VARIETY)]
        elif math.isfinite(high):
            numbers = [high - i / 4 for i in range(_VARIETY)]
        else:
            numbers = [i / 4 for i in range(_VARIETY)]
        for number in numbers:
            typed = _typed(node, number)
            if low <= typed <= high:
                yield typed


def values_for(node: DataNode) -> list[Value]:
    """Distinct valid values of a node (arrays: every item alike)."""
    found: list[Value] = []
    for item in _scalars(node):
        value: Value = (item,) * node.type.count if node.type.is_array else item
        if value not in found:
            found.append(value)
    return found


def other_values(node: DataNode, current: Value, count: int = 1) -> list[Value]:
    """`count` distinct valid values of `node`, none equal to `current`."""
    found = [v for v in values_for(node) if v != current][:count]
    if len(found) < count:
        raise NotApplicable(f"{node.path} has fewer than {count + 1} values to write")
    return found


def outside_value(node: DataNode) -> Value | None:
    """A value of the node's type outside its `min`/`max` (D-RCML-12), or None."""
    base = node.type.base
    item: Scalar
    if base.kind is Kind.INTEGER:
        if node.maximum is not None and node.maximum < base.high:
            item = int(node.maximum) + 1
        elif node.minimum is not None and node.minimum > base.low:
            item = int(node.minimum) - 1
        else:
            return None
    elif base.kind is Kind.FLOAT:
        if node.maximum is not None:
            item = _typed(node, node.maximum + max(1.0, abs(node.maximum)))
        elif node.minimum is not None:
            item = _typed(node, node.minimum - max(1.0, abs(node.minimum)))
        else:
            return None
    else:
        return None
    return (item,) * node.type.count if node.type.is_array else item


# -- exchanges ---------------------------------------------------------------------------------


def check_values(
    ctx: Context, message: Message, nodes: Sequence[DataNode], where: str, rule: str
) -> dict[str, Value]:
    """The values of a READ answer's or a server WRITE's body: with `Content-Type` and
    `Content-Length` (R-RCTP-6), and exactly the values of `nodes` (`rule`)."""
    kind = message.headers.get("Content-Type")
    length = message.headers.get("Content-Length")
    ctx.expect(same_token(kind, VALUES_TYPE), f"Content-Type: {VALUES_TYPE}", f"{kind}", "R-RCTP-6")
    ctx.expect(
        length == str(len(message.body)),
        f"Content-Length: {len(message.body)}",
        f"Content-Length: {length}",
        "R-RCTP-6",
    )
    try:
        return ValuesCodec(nodes, where, rule).decode(message.body)
    except ProtocolError as error:
        names = ", ".join(n.name for n in nodes)
        raise Failed(
            error.rule or rule,
            f"a body holding exactly the values of {where} ({names})",
            f"{error.reason} at body byte {error.offset}",
        ) from None


def check_listed(ctx: Context, message: Message, wanted: Sequence[str], rule: str) -> None:
    """`Nodes` lists exactly `wanted`, in canonical order (R-RCTP-30)."""
    text = message.headers.get("Nodes")
    expected = f"Nodes: {format_nodes(wanted)}"
    if text is None:
        raise Failed(rule, expected, "no Nodes field")
    try:
        listed = parse_nodes(text)
    except ValueTextError as error:
        raise Failed("R-RCTP-30", expected, f"Nodes: {text} ({error})") from None
    ctx.expect(list(listed) == sorted(wanted), expected, f"Nodes: {text}", rule)


def check_allow(ctx: Context, answer: Response, path: str) -> None:
    """405 with `Allow` listing the methods D-RCTP-26 gives the target's kind, in its order."""
    kind = target_kind(ctx.robot, path)
    assert kind is not None  # the cases name nodes of the model
    ctx.expect_status(answer, 405)
    wanted = ALLOW[kind]
    text = answer.headers.get("Allow") or ""
    given = tuple(m.strip(" \t") for m in text.split(",")) if text else ()
    ctx.expect(given == wanted, f"Allow: {', '.join(wanted)}", f"Allow: {text}", "R-RCTP-26")


async def read(ctx: Context, probe: ControlProbe, named: Named) -> dict[str, Value]:
    """The values READ gives; inconclusive when READ fails (the read cases check READ)."""
    answer = await probe.request("READ", named.target, named.fields())
    if answer.status != 200:
        raise Inconclusive(f"READ {named.target} was answered {answer.status} {answer.reason}")
    try:
        return named.codec("R-RCML-30").decode(answer.body)
    except ProtocolError as error:
        raise Inconclusive(f"READ {named.target}: {error.reason}") from None


async def write(
    probe: ControlProbe, named: Named, values: Mapping[str, Value], fields: Fields = ()
) -> Response:
    return await probe.request(
        "WRITE", named.target, [*named.fields(), *fields], named.encode(values)
    )


async def acquire(ctx: Context, probe: ControlProbe, path: str) -> None:
    """ACQUIRE as a precondition: inconclusive if refused (the rctp/priv cases check it)."""
    answer = await probe.request("ACQUIRE", format_target(path))
    if answer.status != 200:
        raise Inconclusive(f"ACQUIRE {path} was answered {answer.status} {answer.reason}")


async def put_back(
    ctx: Context, probe: ControlProbe, named: Named, values: Mapping[str, Value]
) -> None:
    """Write the values a case found back, as well as it can (the robot is shared)."""
    with contextlib.suppress(Exception):
        await asyncio.wait_for(write(probe, named, values), ctx.wait)


async def unheld(ctx: Context) -> None:
    """Wait until no session holds any part of the tree. The sessions of the case before end as
    the server reads their closed connections (R-RCTP-36), which it may do after this case's
    first request; inconclusive if they never end (rctp/priv/close-releases checks that)."""
    probe = await ctx.session()
    loop = asyncio.get_running_loop()
    deadline = loop.time() + _FREE_WAIT * ctx.scale
    while (answer := await probe.request("ACQUIRE", ROOT)).status == 471:
        if loop.time() > deadline:
            break
        await asyncio.sleep(_POLL)
    if answer.status != 200:
        probe.close()
        raise Inconclusive(f"ACQUIRE / was answered {answer.status} {answer.reason}")
    released = await probe.request("RELEASE", ROOT)
    probe.close()
    # D-RCTP-16: RELEASE of a path the session acquired, with no stream set up, is granted;
    # 470 is for a path it does not hold, 455 for one with a writing stream (R-RCTP-35).
    expect_answer(ctx, released, 200, "RELEASE / just after ACQUIRE / was granted", "R-RCTP-35")


async def sessions(ctx: Context, count: int) -> list[ControlProbe]:
    """`count` sessions, once no session holds a privilege (for the serial cases)."""
    await unheld(ctx)
    return [await ctx.session() for _ in range(count)]


async def writer(ctx: Context, named: Named) -> ControlProbe:
    """A session that holds the privilege of `named`'s target (and none other does)."""
    (probe,) = await sessions(ctx, 1)
    await acquire(ctx, probe, named.path)
    return probe


# -- READ --------------------------------------------------------------------------------------


@case(
    "rctp/node/read-normal",
    "READ of a readable data node of a normal access is answered 200 with exactly its value",
    ["R-RCTP-6", "R-RCML-30"],
)
async def read_normal(ctx: Context) -> None:
    named = pick(ctx, lambda d: Permission.READ in d.permission, (AccessType.NORMAL,))
    probe = await ctx.session()
    answer = await probe.request("READ", named.target)
    ctx.expect_status(answer, 200)
    check_values(ctx, answer, named.nodes, named.path, "R-RCML-30")


@case(
    "rctp/node/read-event-all",
    "READ of an event access without Nodes answers every readable node, listed in Nodes",
    ["R-RCTP-30", "R-RCTP-6", "R-RCML-30"],
)
async def read_event_all(ctx: Context) -> None:
    access = event_access(ctx, lambda a: bool(a.readable()), "with a readable node")
    probe = await ctx.session()
    answer = await probe.request("READ", format_target(access.path))
    ctx.expect_status(answer, 200)
    readable = access.readable()
    check_listed(ctx, answer, [n.name for n in readable], "R-RCTP-30")
    check_values(ctx, answer, readable, access.path, "R-RCML-30")


@case(
    "rctp/node/read-event-nodes",
    "READ of an event access with Nodes answers exactly the nodes listed, in canonical order",
    ["R-RCTP-30", "R-RCTP-6", "R-RCML-30"],
)
async def read_event_nodes(ctx: Context) -> None:
    access = event_access(ctx, lambda a: len(a.readable()) >= 2, "with two readable nodes")
    readable = access.readable()
    # The first and the last: the answer must hold them, and not the nodes in between.
    named = Named(access.path, (readable[0], readable[-1]), event=True)
    probe = await ctx.session()
    answer = await probe.request("READ", named.target, named.fields())
    ctx.expect_status(answer, 200)
    check_listed(ctx, answer, [n.name for n in named.nodes], "R-RCTP-30")
    check_values(ctx, answer, named.nodes, access.path, "R-RCML-30")


@case(
    "rctp/node/read-event-nodes-order",
    "READ of an event access whose Nodes is not in canonical order is answered 400",
    ["R-RCTP-30"],
)
async def read_event_nodes_order(ctx: Context) -> None:
    access = event_access(ctx, lambda a: len(a.readable()) >= 2, "with two readable nodes")
    first, last = access.readable()[0].name, access.readable()[-1].name
    probe = await ctx.session()
    answer = await probe.request(
        "READ", format_target(access.path), [("Nodes", f"{last}, {first}")]
    )
    ctx.expect_status(answer, 400)


@case(
    "rctp/node/read-event-nodes-repeated",
    "READ of an event access whose Nodes lists a node twice is answered 400",
    ["R-RCTP-30"],
)
async def read_event_nodes_repeated(ctx: Context) -> None:
    access = event_access(ctx, lambda a: bool(a.readable()), "with a readable node")
    name = access.readable()[0].name
    probe = await ctx.session()
    answer = await probe.request("READ", format_target(access.path), [("Nodes", f"{name}, {name}")])
    ctx.expect_status(answer, 400)


@case(
    "rctp/node/read-event-nodes-unknown",
    "READ of an event access whose Nodes names no data node of the access is answered 400",
    ["R-RCTP-30"],
)
async def read_event_nodes_unknown(ctx: Context) -> None:
    access = event_access(ctx, lambda a: bool(a.readable()), "with a readable node")
    if any(n.name == MISSING for n in access.data):
        raise NotApplicable(f"{access.path} has a node {MISSING}")
    probe = await ctx.session()
    answer = await probe.request("READ", format_target(access.path), [("Nodes", MISSING)])
    ctx.expect_status(answer, 400)


@case(
    "rctp/node/read-percent-encoded",
    "READ of a node whose path segments are percent-encoded reads the node itself",
    ["R-RCTP-15", "R-RCML-30"],
)
async def read_percent_encoded(ctx: Context) -> None:
    named = pick(ctx, lambda d: Permission.READ in d.permission)
    probe = await ctx.session()
    answer = await probe.request("READ", percent_encoded(named.path), named.fields())
    ctx.expect_status(answer, 200, "R-RCTP-15")
    check_values(ctx, answer, named.nodes, named.path, "R-RCML-30")


@case(
    "rctp/node/read-percent-encoded-nodes",
    "READ of an event access whose Nodes names are percent-encoded reads those nodes",
    ["R-RCTP-30", "R-RCML-30"],
)
async def read_percent_encoded_nodes(ctx: Context) -> None:
    access = event_access(ctx, lambda a: bool(a.readable()), "with a readable node")
    node = max(access.readable(), key=lambda n: not n.name.isascii())  # UTF-8 if there is one
    encoded = percent_encoded("/" + node.name)[1:]
    probe = await ctx.session()
    answer = await probe.request("READ", format_target(access.path), [("Nodes", encoded)])
    ctx.expect_status(answer, 200)
    check_listed(ctx, answer, [node.name], "R-RCTP-30")
    check_values(ctx, answer, (node,), access.path, "R-RCML-30")


# -- the node check: 404, 405 (D-RCTP-26) ------------------------------------------------------


@case(
    "rctp/node/read-missing",
    "READ of a path that names no node is answered 404",
    ["R-RCTP-26"],
)
async def read_missing(ctx: Context) -> None:
    path = missing_path(ctx)
    probe = await ctx.session()
    ctx.expect_status(await probe.request("READ", format_target(path)), 404)


@case(
    "rctp/node/write-missing",
    "WRITE of a path that names no node is answered 404, before the privilege is looked at",
    ["R-RCTP-26"],
)
async def write_missing(ctx: Context) -> None:
    path = missing_path(ctx)
    probe = await ctx.session()
    answer = await probe.request("WRITE", format_target(path), body=b"\x00")
    ctx.expect_status(answer, 404)


@case(
    "rctp/node/read-group",
    "READ of a group (or the whole tree) is answered 405 with Allow: ACQUIRE, RELEASE",
    ["R-RCTP-26"],
)
async def read_group(ctx: Context) -> None:
    group = next((n for n in ctx.robot.nodes.values() if isinstance(n, GroupNode)), None)
    path = group.path if group is not None else ROOT
    probe = await ctx.session()
    check_allow(ctx, await probe.request("READ", format_target(path)), path)


@case(
    "rctp/node/read-normal-access",
    "READ of a normal access node (not of its data nodes) is answered 405 with Allow",
    ["R-RCTP-26"],
)
async def read_normal_access(ctx: Context) -> None:
    access = ctx.access(AccessType.NORMAL)
    probe = await ctx.session()
    check_allow(ctx, await probe.request("READ", format_target(access.path)), access.path)


@case(
    "rctp/node/setup-normal-data",
    "SETUP of a data node of a normal access is answered 405 with Allow of its four methods",
    ["R-RCTP-26"],
)
async def setup_normal_data(ctx: Context) -> None:
    named = pick(ctx, lambda _: True, (AccessType.NORMAL,))
    probe = await ctx.session()
    check_allow(ctx, await probe.request("SETUP", named.target), named.path)


@case(
    "rctp/node/read-event-data",
    "READ of a data node of an event access (not of the access) is answered 405 with Allow",
    ["R-RCTP-26"],
)
async def read_event_data(ctx: Context) -> None:
    access = event_access(ctx, lambda a: bool(a.readable()), "with a readable node")
    node = access.readable()[0]
    probe = await ctx.session()
    check_allow(ctx, await probe.request("READ", format_target(node.path)), node.path)


@case(
    "rctp/node/read-stream-access",
    "READ of a stream access is answered 405 with the Allow of a stream access",
    ["R-RCTP-31", "R-RCTP-26"],
)
async def read_stream_access(ctx: Context) -> None:
    access = ctx.access(AccessType.STREAM, Permission.READ, lambda a: bool(a.readable()))
    probe = await ctx.session()
    check_allow(ctx, await probe.request("READ", format_target(access.path)), access.path)


@case(
    "rctp/node/write-stream-access",
    "WRITE of a stream access is answered 405, before the privilege is looked at",
    ["R-RCTP-31", "R-RCTP-26"],
)
async def write_stream_access(ctx: Context) -> None:
    access = ctx.access(AccessType.STREAM, Permission.WRITE, lambda a: bool(a.writable()))
    named = Named(access.path, access.writable(), event=True)
    body = named.encode({n.name: values_for(n)[0] for n in named.nodes})
    probe = await ctx.session()
    check_allow(ctx, await probe.request("WRITE", named.target, body=body), access.path)


@case(
    "rctp/node/read-stream-data",
    "READ of a data node of a stream access is answered 405",
    ["R-RCTP-31", "R-RCTP-26"],
)
async def read_stream_data(ctx: Context) -> None:
    node = pick(ctx, lambda d: Permission.READ in d.permission, (AccessType.STREAM,)).node
    probe = await ctx.session()
    check_allow(ctx, await probe.request("READ", format_target(node.path)), node.path)


@case(
    "rctp/node/write-stream-data",
    "WRITE of a writable data node of a stream access is answered 405",
    ["R-RCTP-31", "R-RCTP-26"],
)
async def write_stream_data(ctx: Context) -> None:
    node = pick(ctx, lambda d: Permission.WRITE in d.permission, (AccessType.STREAM,)).node
    body = Named(node.path, (node,), event=False).encode({node.name: values_for(node)[0]})
    probe = await ctx.session()
    answer = await probe.request("WRITE", format_target(node.path), body=body)
    check_allow(ctx, answer, node.path)


# -- the permission: 403 (R-RCTP-27) -----------------------------------------------------------


async def _unwritable(ctx: Context, kind: AccessType) -> None:
    """A WRITE of a node without w of an access of `kind`, not holding it, is answered 403."""
    named = pick(ctx, lambda d: Permission.WRITE not in d.permission, (kind,), "read-only node")
    probe = await ctx.session()
    answer = await write(probe, named, {named.node.name: values_for(named.node)[0]})
    ctx.expect_status(answer, 403)


@case(
    "rctp/node/write-unwritable",
    "WRITE of a data node without w is answered 403, not 470: the permission is checked first",
    ["R-RCTP-27", "R-RCML-31"],
)
async def write_unwritable(ctx: Context) -> None:
    await _unwritable(ctx, AccessType.NORMAL)


@case(
    "rctp/node/write-event-unwritable",
    "WRITE of an event access whose Nodes lists a node without w is answered 403",
    ["R-RCTP-27", "R-RCML-31"],
)
async def write_event_unwritable(ctx: Context) -> None:
    await _unwritable(ctx, AccessType.EVENT)


# -- WRITE bodies: 411, 415, 422, 400 (serial: they hold the privilege) ------------------------


def _valid_write(
    ctx: Context,
    fits: Callable[[bytes], bool] = lambda body: True,
    what: str = "writable data node",
) -> tuple[Named, bytes]:
    """A writable node whose valid body `fits` (readable where the robot has one: `writable`),
    and that body."""

    def body(node: DataNode) -> bytes:
        return Named(node.path, (node,), event=False).encode({node.name: values_for(node)[-1]})

    named = writable(ctx, lambda node: fits(body(node)), what)
    return named, named.encode({named.node.name: values_for(named.node)[-1]})


async def _refused(
    ctx: Context, named: Named, body: bytes, status: int, fields: Fields = ()
) -> None:
    """A WRITE of `named` with `body`, sent holding the privilege, is answered `status`; a
    readable node is read before and after, and must not have changed (R-RCTP-28)."""
    probe = await writer(ctx, named)
    readable = Permission.READ in named.node.permission
    if not readable:
        ctx.cannot_check(f"that the WRITE changed nothing: {named.node.path} cannot be read")
    before = await read(ctx, probe, named) if readable else None
    answer = await probe.request("WRITE", named.target, [*named.fields(), *fields], body)
    after = await read(ctx, probe, named) if before is not None else None
    if after != before and before is not None:
        await put_back(ctx, probe, named, before)
    ctx.expect_status(answer, status)
    rule = "R-RCTP-28" if status == 422 else None
    ctx.expect(after == before, f"{named.node.path} left at {before}", f"{after}", rule)


@case(
    "rctp/node/write-short",
    "WRITE whose body is one byte short of the node's value is answered 422, changing nothing",
    ["R-RCTP-28"],
    serial=True,
)
async def write_short(ctx: Context) -> None:
    # One byte short of a 1-byte value is no body at all, which D-RCTP-15 answers 411
    # (rctp/node/write-no-length): this case needs a value of 2 bytes or more.
    named, body = _valid_write(
        ctx, lambda body: len(body) >= 2, "writable data node of 2 bytes or more"
    )
    await _refused(ctx, named, body[:-1], 422)


@case(
    "rctp/node/write-long",
    "WRITE whose body holds a byte after the node's value is answered 422, changing nothing",
    ["R-RCTP-28"],
    serial=True,
)
async def write_long(ctx: Context) -> None:
    named, body = _valid_write(ctx)
    await _refused(ctx, named, body + b"\x00", 422)


@case(
    "rctp/node/write-wrong-type",
    "WRITE whose body holds a value of another width than the node's type is answered 422",
    ["R-RCTP-28"],
    serial=True,
)
async def write_wrong_type(ctx: Context) -> None:
    named = pick(
        ctx,
        lambda d: Permission.WRITE in d.permission and not d.type.base.sized,
        what="writable data node of a fixed-size type",
    )
    size = named.node.type.max_encoded_size
    # A float64 where a narrower type is, a float32 where a 64-bit type is.
    body = struct.pack(">d", 0.0) if size < 8 else struct.pack(">f", 0.0)
    await _refused(ctx, named, body, 422)


@case(
    "rctp/node/write-out-of-range",
    "WRITE of a value outside the node's min/max is answered 422, changing nothing",
    ["R-RCTP-28"],
    serial=True,
)
async def write_out_of_range(ctx: Context) -> None:
    named = pick(
        ctx,
        lambda d: Permission.WRITE in d.permission and outside_value(d) is not None,
        what="writable data node with a range",
    )
    outside = outside_value(named.node)
    assert outside is not None
    body = named.encode({named.node.name: outside})
    await _refused(ctx, named, body, 422)


@case(
    "rctp/node/write-media-type",
    "WRITE whose body is not application/rctp-values is answered 415",
    ["R-RCTP-6"],
    serial=True,
)
async def write_media_type(ctx: Context) -> None:
    named, body = _valid_write(ctx)
    await _refused(ctx, named, body, 415, [("Content-Type", TEXT_TYPE)])


@case(
    "rctp/node/tokens-in-any-case",
    "WRITE typed Application/RCTP-Values and SETUP of Transport UDP;Client_Port=P;MODE=Read are "
    "taken as their lower-case spellings",
    ["R-RCTP-59"],
    serial=True,
)
async def tokens_in_any_case(ctx: Context) -> None:
    # D-RCTP-30: the grammar's quoted text, but for methods and the version, in any case.
    named, body = _valid_write(ctx)
    probe = await writer(ctx, named)
    typed = [*named.fields(), ("Content-Type", "Application/RCTP-Values")]
    answer = await probe.request("WRITE", named.target, typed, body)
    ctx.expect_status(answer, 200, what="WRITE with Content-Type: Application/RCTP-Values")
    stream = first(ctx, AccessType.STREAM)
    if stream is None:
        raise NotApplicable("the robot has no stream access: only the media type was checked")
    port = probe.local[1]  # nothing is sent to it before GO
    transport = f"UDP;Client_Port={port};MODE=Read"
    answer = await probe.request("SETUP", format_target(stream.path), [("Transport", transport)])
    ctx.expect_status(answer, 200, what=f"SETUP with Transport: {transport}")


@case(
    "rctp/node/write-no-length",
    "WRITE without Content-Length is answered 411",
    ["R-RCTP-6"],
    serial=True,
)
async def write_no_length(ctx: Context) -> None:
    named = writable(ctx)
    await _refused(ctx, named, b"", 411, [("Content-Type", VALUES_TYPE)])


@case(
    "rctp/node/write-event-no-nodes",
    "WRITE of an event access without Nodes is answered 400",
    ["R-RCTP-30"],
    serial=True,
)
async def write_event_no_nodes(ctx: Context) -> None:
    access = event_access(ctx, lambda a: bool(a.writable()), "with a writable node")
    writable = Named(access.path, access.writable(), event=True)
    body = writable.encode({n.name: values_for(n)[0] for n in writable.nodes})
    probe = await writer(ctx, writable)
    answer = await probe.request("WRITE", writable.target, body=body)
    ctx.expect_status(answer, 400)


# -- WRITE that succeeds -----------------------------------------------------------------------


@case(
    "rctp/node/write-read-back",
    "An event WRITE of every rw node is answered 200, and READ then gives the values written",
    ["R-RCTP-29"],
    serial=True,
)
async def write_read_back(ctx: Context) -> None:
    def fits(access: AccessNode) -> bool:
        return any(RW in n.permission and len(values_for(n)) > 1 for n in access.data)

    access = event_access(ctx, fits, "with a readable and writable node")
    nodes = tuple(n for n in access.data if RW in n.permission and len(values_for(n)) > 1)
    named = Named(access.path, nodes, event=True)
    probe = await writer(ctx, named)
    before = await read(ctx, probe, named)
    values = {n.name: other_values(n, before[n.name])[0] for n in nodes}
    answer = await write(probe, named, values)
    ctx.expect_status(answer, 200)
    after = await read(ctx, probe, named)
    await put_back(ctx, probe, named, before)
    ctx.expect(after == values, f"{access.path} = {values}", f"{after}")


@case(
    "rctp/node/write-atomic",
    "An event WRITE with one value out of range is answered 422 and applies none of its values",
    ["R-RCTP-29", "R-RCTP-28"],
    serial=True,
)
async def write_atomic(ctx: Context) -> None:
    def fits(access: AccessNode) -> bool:
        both = [n for n in access.data if RW in n.permission]
        return len(both) >= 2 and any(outside_value(n) is not None for n in both)

    access = event_access(ctx, fits, "with two rw nodes, one with a range")
    nodes = tuple(n for n in access.data if RW in n.permission)
    named = Named(access.path, nodes, event=True)
    bad = next(n for n in nodes if outside_value(n) is not None)
    probe = await writer(ctx, named)
    before = await read(ctx, probe, named)
    values = {n.name: other_values(n, before[n.name])[0] for n in nodes if n is not bad}
    outside = outside_value(bad)
    assert outside is not None
    values[bad.name] = outside
    answer = await write(probe, named, values)
    after = await read(ctx, probe, named)
    if after != before:
        await put_back(ctx, probe, named, before)
    ctx.expect_status(answer, 422, "R-RCTP-28")
    ctx.expect(after == before, f"{access.path} left at {before}", f"{after}")
