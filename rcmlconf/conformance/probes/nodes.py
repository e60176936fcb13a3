"""What the cases of data nodes share — rctp/node, rctp/priv, rctp/event, rctp/value: valid and
invalid values of a node, checks of a values body, of `Nodes` and of `Allow` (D-RCTP-26's table,
written out again), and READ, WRITE and the privilege as preconditions (specs/rctp-2.0.md §3
D-RCTP-25, D-RCTP-26, §4 D-RCTP-16, §5 D-RCTP-17; specs/rcml-2.0.md D-RCML-12).

The nodes are picked from the robot's RCML (`conformance.picks`). The privilege is the whole
server's: a case that ACQUIREs runs alone (`serial`) and starts once no session holds anything
(`sessions`: the sessions of the case before end when the server reads their closed connections,
R-RCTP-36).
"""

from __future__ import annotations

import asyncio
import contextlib
import math
import struct
from collections.abc import Iterator, Mapping, Sequence

from rcmlconf.conformance.context import Context, expect_answer
from rcmlconf.conformance.picks import Named
from rcmlconf.conformance.probes.control import ControlProbe, Fields
from rcmlconf.conformance.verdicts import Failed, Inconclusive, NotApplicable
from rcmlconf.errors import ProtocolError, ValueTextError
from rcmlconf.rcml.model import DataNode
from rcmlconf.rctp.allowed import TargetKind, target_kind
from rcmlconf.rctp.bodies import ValuesCodec
from rcmlconf.rctp.fields import format_nodes, parse_nodes, same_token
from rcmlconf.rctp.messages import VALUES_TYPE, Message, Response
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
