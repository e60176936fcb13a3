"""rctp/node, WRITE bodies: a body that is short, long, of another width or out of range is answered
422 and changes nothing, one without Content-Length 411, of another media type 415, an event
WRITE without `Nodes` 400; a valid one is applied, an event WRITE whole or not at all, and tokens
are taken in any case (specs/rctp-2.0.md §3 D-RCTP-15, D-RCTP-25, D-RCTP-30, R-RCTP-6,
R-RCTP-28 to R-RCTP-30, R-RCTP-59).

A WRITE needs the privilege before its body is judged (D-RCTP-25), and the privilege is the whole
server's: every case here ACQUIREs, so runs alone (`serial`), and reads back (and puts back) the
node it wrote where it can.
"""

from __future__ import annotations

import struct
from collections.abc import Callable

from rcmlconf.conformance.context import Context
from rcmlconf.conformance.picks import RW, Named, event_access, first, pick, writable
from rcmlconf.conformance.probes.control import Fields
from rcmlconf.conformance.probes.nodes import (
    other_values,
    outside_value,
    put_back,
    read,
    values_for,
    write,
    writer,
)
from rcmlconf.conformance.registry import case
from rcmlconf.conformance.verdicts import NotApplicable
from rcmlconf.rcml.model import AccessNode, AccessType, DataNode, Permission
from rcmlconf.rctp.messages import TEXT_TYPE, VALUES_TYPE
from rcmlconf.rctp.targets import format_target

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
