"""rctp/node, READ and the node check: what READ gives of a normal data node and of an event access
(with and without `Nodes`, percent-encoded paths and names), and what a READ, WRITE or SETUP of a
target that cannot take it is answered — 404 for no node, 405 with D-RCTP-26's `Allow` for the
wrong kind of node, 403 for a WRITE of a node without w (specs/rctp-2.0.md §3 D-RCTP-25,
D-RCTP-26, §5 D-RCTP-17, R-RCTP-6, R-RCTP-15, R-RCTP-26, R-RCTP-27, R-RCTP-30, R-RCTP-31).

None of these cases needs the privilege: D-RCTP-25 checks the node and the permission before it.
"""

from __future__ import annotations

from rcmlconf.conformance.context import Context
from rcmlconf.conformance.picks import MISSING, Named, event_access, missing_path, pick
from rcmlconf.conformance.probes.nodes import (
    check_allow,
    check_listed,
    check_values,
    values_for,
    write,
)
from rcmlconf.conformance.registry import case
from rcmlconf.conformance.verdicts import NotApplicable
from rcmlconf.rcml.model import AccessType, GroupNode, Permission
from rcmlconf.rctp.targets import ROOT, format_target

# -- what a READ or WRITE names ----------------------------------------------------------------


def percent_encoded(path: str) -> str:
    """`path` with the first character of every segment percent-encoded (D-RCTP-7)."""
    segments = []
    for segment in format_target(path)[1:].split("/"):
        if not segment.startswith("%"):
            segment = "".join(f"%{b:02X}" for b in segment[0].encode()) + segment[1:]
        segments.append(segment)
    return "/" + "/".join(segments)


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
