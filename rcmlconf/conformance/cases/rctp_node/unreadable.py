"""rctp/node/read-unreadable, read-event-unreadable: READ of a node whose effective permission
has no `r` (specs/rctp-2.0.md D-RCTP-16, D-RCTP-25, R-RCTP-27; rcml-2.0.md D-RCML-8,
R-RCML-31).

The permission is a ceiling for reading as much as for writing: a server that checks it for
WRITE only would read out a write-only node (a setpoint, a password) and pass every WRITE case.
READ needs no privilege, so 403 is the answer whether or not anyone holds the node. Robots whose
every node is readable (the reference's) make these cases not applicable.
"""

from __future__ import annotations

from rcmlconf.conformance.context import Context, expect_answer
from rcmlconf.conformance.picks import Named, pick
from rcmlconf.conformance.registry import case
from rcmlconf.conformance.verdicts import NotApplicable
from rcmlconf.rcml.model import AccessNode, AccessType, DataNode, Permission


def _unreadable(node: DataNode) -> bool:
    return Permission.READ not in node.permission


@case(
    "rctp/node/read-unreadable",
    "READ of a data node of a normal access without r is answered 403",
    ["R-RCTP-27", "R-RCML-31"],
)
async def read_unreadable(ctx: Context) -> None:
    named = pick(ctx, _unreadable, (AccessType.NORMAL,), "data node without r")
    probe = await ctx.session()
    answer = await probe.request("READ", named.target)
    expect_answer(ctx, answer, 403, f"READ {named.target}", "R-RCTP-27")


@case(
    "rctp/node/read-event-unreadable",
    "READ of an event access whose Nodes lists a node without r, alone or after a readable one,"
    " is answered 403",
    ["R-RCTP-27", "R-RCML-31"],
)
async def read_event_unreadable(ctx: Context) -> None:
    access, node = _event_unreadable(ctx)
    readable = access.readable()
    listings: list[tuple[DataNode, ...]] = [(node,)]
    if readable:
        # D-RCTP-17: the values of one READ go together; a readable node first must not let
        # the others through.
        listings.append(tuple(sorted((readable[0], node), key=lambda d: d.name.encode())))
    probe = await ctx.session()
    for nodes in listings:
        named = Named(access.path, nodes, event=True)
        answer = await probe.request("READ", named.target, named.fields())
        listed = ", ".join(n.name for n in nodes)
        expect_answer(ctx, answer, 403, f"READ {named.target} of {listed}", "R-RCTP-27")


def _event_unreadable(ctx: Context) -> tuple[AccessNode, DataNode]:
    """An event access and one of its data nodes without r."""
    for access in ctx.robot.access_nodes():
        if access.type is not AccessType.EVENT:
            continue
        node = next((d for d in access.data if _unreadable(d)), None)
        if node is not None:
            return access, node
    raise NotApplicable("the robot has no data node without r of an event access")
