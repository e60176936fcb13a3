"""rctp/value: the values a server takes and gives (specs/rcml-2.0.md D-RCML-4, D-RCML-9 to
D-RCML-12, R-RCML-29, R-RCML-30; specs/rctp-2.0.md R-RCTP-28, R-RCTP-58).

For each flaw of `conformance.flaws` (a bool byte other than 0x00 and 0x01, a string longer than
its size, NaN where a range is declared, ...) two cases: a WRITE holding it, of a node of a normal
access and of one of an event access where the robot has them, is answered 422 and changes nothing
(R-RCTP-28); a DATA payload holding it is ignored whole (R-RCTP-58). Each picks a node that can
have the flaw, readable where the robot has one (only a READ shows that nothing changed), and is
not applicable, naming what the robot lacks, where it has none. Then the order values travel in:
canonical, never the RCML's document order (R-RCML-29), read and written.

The WRITE and DATA cases hold the privilege, which is the whole server's: they run alone
(`serial`), as rctp/node's do.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable

from rcmlconf.conformance.context import Context
from rcmlconf.conformance.flaws import Bad, Flaw, flawed, has, spliced
from rcmlconf.conformance.picks import RW, Named, parent_of, writable
from rcmlconf.conformance.probes.control import ControlProbe
from rcmlconf.conformance.probes.nodes import (
    acquire,
    other_values,
    put_back,
    read,
    sessions,
    values_for,
    write,
    writer,
)
from rcmlconf.conformance.probes.stream_writing import Writing
from rcmlconf.conformance.registry import case
from rcmlconf.conformance.verdicts import Failed, Inconclusive, NotApplicable
from rcmlconf.rcml.model import AccessNode, AccessType, DataNode, Permission
from rcmlconf.rctp.fields import format_nodes
from rcmlconf.rctp.targets import format_target
from rcmlconf.values import Value
from rcmlconf.values.binary import encode_value
from rcmlconf.values.shown import values_text

#: How many times the canonical-order case reads the access whole and node by node, looking for
#: a moment the values stand still (a robot's sensors move).
_TRIES = 5

# -- WRITE ---------------------------------------------------------------------------------------


def _access_type(ctx: Context, node: DataNode) -> AccessType | None:
    access = ctx.robot.node(parent_of(node.path))
    return access.type if isinstance(access, AccessNode) else None


def _targets(ctx: Context, flaw: Flaw) -> list[Named]:
    """A writable data node that can have `flaw` of a normal access and one of an event access,
    as far as the robot has them, each readable where it can be (`writable`)."""
    found = []
    for kind in (AccessType.NORMAL, AccessType.EVENT):

        def fits(node: DataNode, kind: AccessType = kind) -> bool:
            return _access_type(ctx, node) is kind and has(node, flaw)

        with contextlib.suppress(NotApplicable):
            found.append(writable(ctx, fits))
    if not found:
        raise NotApplicable(
            f"the robot has no writable data node {flaw.needs} in a normal or event access"
        )
    return found


async def _refused(ctx: Context, probe: ControlProbe, named: Named, bad: Bad) -> None:
    """A WRITE of `bad` is answered 422 and changes nothing (R-RCTP-28). A readable node is first
    written a valid value other than the one a receiver letting the flaw through would take, and
    read before and after."""
    node = named.node
    listed = f" (Nodes: {node.name})" if named.event else ""
    what = f"WRITE {named.path}{listed} holding {bad.what}"
    before = None
    if Permission.READ not in node.permission:
        ctx.cannot_check(f"that the WRITE changed nothing: {node.path} cannot be read")
    else:
        start = next((v for v in values_for(node) if v != bad.lenient), None)
        if start is not None:
            await write(probe, named, {node.name: start})  # READ says what holds
        before = await read(ctx, probe, named)
    answer = await probe.request("WRITE", named.target, named.fields(), bad.data)
    ctx.expect_status(answer, 422, "R-RCTP-28", what=what)
    after = await read(ctx, probe, named) if before is not None else None
    kept = " ".join(values_text(named.nodes, before or {}))
    ctx.expect(
        after == before, f"{kept} left by {what}", " ".join(values_text(named.nodes, after or {}))
    )


async def _write_flawed(ctx: Context, flaw: Flaw) -> None:
    """Every encoding of `flaw` written to each target, holding its privilege; what a readable
    target held is written back at the end."""
    targets = _targets(ctx, flaw)
    (probe,) = await sessions(ctx, 1)
    for named in targets:
        await acquire(ctx, probe, named.path)
    for named in targets:
        readable = Permission.READ in named.node.permission
        found = await read(ctx, probe, named) if readable else None
        try:
            for bad in flawed(named.node, flaw):
                await _refused(ctx, probe, named, bad)
        finally:
            if found is not None:  # the robot is shared: what the case wrote goes
                await put_back(ctx, probe, named, found)


# -- DATA ----------------------------------------------------------------------------------------


async def _data_flawed(ctx: Context, flaw: Flaw) -> None:
    """DATA payloads, each holding a valid value of every writable node but one encoded with
    `flaw`, are ignored whole: what is read back stays (R-RCTP-58); those values written validly
    then show, so the check could have seen them applied."""

    def fits(access: AccessNode) -> bool:
        return any(has(n, flaw) for n in access.writable())

    streams = [a for a in ctx.robot.access_nodes() if a.type is AccessType.STREAM and fits(a)]
    if not streams:
        raise NotApplicable(
            f"the robot has no stream access with a writable data node {flaw.needs}"
        )
    writing = await Writing.open(ctx, fits)
    node = next(n for n in writing.writer.nodes if has(n, flaw))
    bads = flawed(node, flaw)
    _, other = await writing.two_values()
    for bad in bads:
        writing.send(body=spliced(writing.writer.nodes, other, node, bad.data))
    sent = f"DATA payloads holding {node.name} = {'; '.join(b.what for b in bads)} with {other}"
    try:
        await writing.holds("R-RCTP-58", sent)
    except Failed as failed:
        if failed.requirement != "R-RCTP-40":
            raise
        # What the server sends back no longer decodes: it holds the flawed value it took.
        raise Failed("R-RCTP-58", f"{sent} ignored", failed.actual) from None
    await writing.shows(other)
    await writing.finish()


def _register(flaw: Flaw) -> None:
    """The WRITE case and the DATA case of one flaw."""
    malformed = ["R-RCML-30"] if flaw.malformed else []

    @case(
        f"rctp/value/write-{flaw.value}",
        f"A WRITE holding {flaw.about} is answered 422 and changes nothing (normal and event"
        " access)",
        ["R-RCTP-28", *malformed],
        serial=True,
    )
    async def write_flaw(ctx: Context) -> None:
        await _write_flawed(ctx, flaw)

    @case(
        f"rctp/value/data-{flaw.value}",
        f"A DATA payload holding {flaw.about} is ignored whole",
        ["R-RCTP-58", *malformed],
        serial=True,
    )
    async def data_flaw(ctx: Context) -> None:
        await _data_flawed(ctx, flaw)


for _flaw in Flaw:
    _register(_flaw)


# -- canonical order (D-RCML-4) ------------------------------------------------------------------


def _reordered(
    ctx: Context, chosen: Callable[[AccessNode], tuple[DataNode, ...]], what: str
) -> tuple[AccessNode, tuple[DataNode, ...]]:
    """An event access and its `chosen` data nodes, two or more, that stand in the RCML in
    another order than canonical order: only they tell the two orders apart."""
    for access in ctx.robot.access_nodes():
        nodes = chosen(access)
        if access.type is not AccessType.EVENT or len(nodes) < 2:
            continue
        if ctx.robot.in_document_order(nodes) != nodes:
            return access, nodes
    raise NotApplicable(
        f"the robot has no event access whose {what} data nodes stand in its RCML in another"
        " order than canonical order (D-RCML-4): a server using document order would send the"
        " same bytes"
    )


async def _one_by_one(
    ctx: Context, probe: ControlProbe, access: AccessNode, nodes: tuple[DataNode, ...]
) -> dict[str, bytes]:
    """The body of a READ of each node alone (Nodes naming it): its value's bytes."""
    found = {}
    for node in nodes:
        answer = await probe.request(
            "READ", format_target(access.path), [("Nodes", format_nodes([node.name]))]
        )
        if answer.status != 200:
            raise Inconclusive(f"READ of {node.path} alone was answered {answer.status}")
        found[node.name] = answer.body
    return found


async def _values_alone(
    ctx: Context, probe: ControlProbe, access: AccessNode, nodes: tuple[DataNode, ...]
) -> dict[str, Value]:
    """The value of each node, READ alone: the order of several cannot garble it."""
    found: dict[str, Value] = {}
    for node in nodes:
        found |= await read(ctx, probe, Named(access.path, (node,), event=True))
    return found


@case(
    "rctp/value/canonical-order-read",
    "READ of an event access gives its values in canonical order, not the RCML's document order:"
    " each as a READ of that node alone gives it",
    ["R-RCML-29"],
)
async def canonical_order_read(ctx: Context) -> None:
    access, nodes = _reordered(ctx, AccessNode.readable, "readable")
    probe = await ctx.session()
    for _ in range(_TRIES):
        alone = await _one_by_one(ctx, probe, access, nodes)
        whole = await probe.request("READ", format_target(access.path))
        if whole.status != 200:
            raise Inconclusive(f"READ of {access.path} was answered {whole.status}")
        if await _one_by_one(ctx, probe, access, nodes) == alone:
            break
    else:
        raise Inconclusive(f"the values of {access.path} changed between every READ of them")
    canonical = b"".join(alone[n.name] for n in nodes)
    document = b"".join(alone[n.name] for n in ctx.robot.in_document_order(nodes))
    if canonical == document:
        raise Inconclusive(f"the values of {access.path} now give the same bytes in either order")
    names = ", ".join(n.name for n in nodes)
    ctx.expect(
        whole.body == canonical,
        f"the values of {names} in that order: {canonical.hex()}",
        whole.body.hex() + (" (document order)" if whole.body == document else ""),
    )


@case(
    "rctp/value/canonical-order-write",
    "An event WRITE's values are taken in canonical order, not the RCML's document order: READs"
    " of each node alone give what was written",
    ["R-RCML-29"],
    serial=True,
)
async def canonical_order_write(ctx: Context) -> None:
    def both(access: AccessNode) -> tuple[DataNode, ...]:
        return tuple(n for n in access.data if RW in n.permission and len(values_for(n)) > 1)

    access, nodes = _reordered(ctx, both, "readable and writable")
    named = Named(access.path, nodes, event=True)
    probe = await writer(ctx, named)
    before = await _values_alone(ctx, probe, access, nodes)
    values = {n.name: other_values(n, before[n.name])[0] for n in nodes}
    document = b"".join(
        encode_value(n.type, values[n.name]) for n in ctx.robot.in_document_order(nodes)
    )
    if named.encode(values) == document:
        raise Inconclusive(f"the values chosen give the same bytes in either order: {values}")
    answer = await write(probe, named, values)
    alone = await _values_alone(ctx, probe, access, nodes)
    await put_back(ctx, probe, named, before)
    names = ", ".join(n.name for n in nodes)
    ctx.expect_status(answer, 200, what=f"WRITE of {names} in canonical order")
    ctx.expect(alone == values, f"{values} read back node by node", str(alone))
