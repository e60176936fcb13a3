"""rctp/node/write-event-nodes-order, write-event-nodes-repeated: the Nodes of a WRITE are held
to the rules of a READ's (specs/rctp-2.0.md D-RCTP-17, D-RCTP-25, R-RCTP-30).

The READ cases check the canonical order and each node once; a server that parses a WRITE's
`Nodes` on a path of its own, decoding the body in the order listed, passed them all. D-RCTP-25
checks `Nodes` before the permission and the privilege, so no privilege is needed to be refused:
the WRITE never reaches the robot.
"""

from __future__ import annotations

from rcmlconf.conformance.context import Context, expect_answer
from rcmlconf.conformance.picks import Named, event_access
from rcmlconf.conformance.probes.nodes import values_for
from rcmlconf.conformance.registry import case
from rcmlconf.rcml.model import DataNode


async def _refused_listing(ctx: Context, order: tuple[int, ...]) -> None:
    """A WRITE of the first event access with two writable nodes, listing them (by their index
    in canonical order) as `order` says, its body in that order: answered 400."""
    access = event_access(ctx, lambda a: len(a.writable()) >= 2, "with two writable nodes")
    writable = access.writable()
    listed: list[DataNode] = [writable[index] for index in order]
    body = b"".join(
        Named(access.path, (node,), event=True).encode({node.name: values_for(node)[0]})
        for node in listed
    )
    names = ", ".join(node.name for node in listed)
    probe = await ctx.session()
    answer = await probe.request(
        "WRITE", Named(access.path, (), event=True).target, [("Nodes", names)], body
    )
    expect_answer(ctx, answer, 400, f"WRITE {access.path} with Nodes: {names}", "R-RCTP-30")


@case(
    "rctp/node/write-event-nodes-order",
    "WRITE of an event access whose Nodes is not in canonical order is answered 400",
    ["R-RCTP-30"],
)
async def write_event_nodes_order(ctx: Context) -> None:
    await _refused_listing(ctx, (-1, 0))


@case(
    "rctp/node/write-event-nodes-repeated",
    "WRITE of an event access whose Nodes lists a node twice is answered 400",
    ["R-RCTP-30"],
)
async def write_event_nodes_repeated(ctx: Context) -> None:
    await _refused_listing(ctx, (0, 0))
