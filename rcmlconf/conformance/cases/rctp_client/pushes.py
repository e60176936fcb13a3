"""rctp/client, the server's data-change WRITEs (D-RCTP-27) in step 5 of D-RCTP-31's scenario:
what an RCTP/2.0 client under test answers to a push of its event access while it plays and while
it is paused, with bodies and `Nodes` right and wrong, and which values it takes, as the WRITE of
the access it sends after its PAUSE shows (R-RCTP-24, R-RCTP-30, R-RCTP-61, R-RCTP-68)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from rcmlconf.conformance.cases.rctp_client.scenario import (
    edge,
    event_access,
    scenario_case,
    until_event_go,
)
from rcmlconf.conformance.context import Context
from rcmlconf.conformance.probes.played import PlayedServer, Seen, path_of
from rcmlconf.conformance.verdicts import Inconclusive
from rcmlconf.rcml.model import AccessNode, DataNode
from rcmlconf.rctp.bodies import ValuesCodec
from rcmlconf.rctp.messages import Request, Response
from rcmlconf.values import Value

#: The `Nodes` a push lists, from the names of the nodes it carries in canonical order (D-RCML-4).
Listing = Callable[[list[str]], list[str]]
#: What the client's WRITE after its PAUSE holds when it took no refused push (R-RCTP-61).
NOT_TAKEN = "the values it had before: the refused push not taken"


@scenario_case(
    "rctp/client/event-push-taken",
    "A data-change WRITE of the server's is answered 200 and its values are the client's newest"
    " (the scenario writes them back, step 5)",
    ["R-RCTP-61", "R-RCTP-24", "R-RCTP-3"],
)
async def event_push_taken(ctx: Context) -> None:
    push = await _push(ctx)
    ctx.expect_status(push.answer, 200, "R-RCTP-24")
    push.written_back(ctx, push.pushed, "the pushed values written back")


@scenario_case(
    "rctp/client/event-push-refused",
    "A data-change WRITE whose body does not decode is refused (400 or 422) and not taken",
    ["R-RCTP-61", "R-RCTP-24", "R-RCTP-3"],
)
async def event_push_refused(ctx: Context) -> None:
    push = await _push(ctx, lambda pushed, codec: codec.encode(pushed)[:-1])
    answer = push.answer
    ctx.expect(
        answer.status in (400, 422),
        "400 or 422: the body is one byte short",
        f"{answer.status} {answer.reason}",
        "R-RCTP-24",
    )
    push.written_back(ctx, push.before, NOT_TAKEN)


@scenario_case(
    "rctp/client/event-push-out-of-range",
    "A data-change WRITE holding a value outside its node's range is not taken if refused (422),"
    " and taken if answered 200",
    ["R-RCTP-61", "R-RCTP-3"],
)
async def event_push_out_of_range(ctx: Context) -> None:
    ranged = [n for n in event_access(ctx).writable() if n.maximum is not None]
    if not ranged:
        raise Inconclusive(f"{event_access(ctx).path} has no writable node with a max")
    node = ranged[0]
    assert node.maximum is not None
    over = node.maximum * 2 + 1

    def beyond(pushed: dict[str, Value], codec: ValuesCodec[DataNode]) -> bytes:
        pushed[node.name] = over
        return codec.encode(pushed)

    push = await _push(ctx, beyond)
    # 422 is the status for a value outside a node's range (D-RCTP-8's table); R-RCTP-61 binds
    # the client to what it answered either way.
    if push.answer.status == 200:
        push.written_back(ctx, push.pushed, f"{node.name}={over:g} taken, as answered 200")
    else:
        push.written_back(
            ctx,
            push.before,
            f"the values it had before: {node.name}={over:g}"
            f" refused ({push.answer.status}), not taken",
        )


@scenario_case(
    "rctp/client/event-push-unknown-node",
    "A data-change WRITE whose Nodes names a node its access lacks is refused with 400 and not"
    " taken",
    ["R-RCTP-30", "R-RCTP-61", "R-RCTP-24", "R-RCTP-3"],
)
async def event_push_unknown_node(ctx: Context) -> None:
    # `ghost` is no node of the access: a client that decodes by position alone takes it.
    push = await _push(
        ctx,
        lambda pushed, codec: codec.encode(pushed) + b"\x00",
        listing=lambda names: sorted([*names, "ghost"]),
    )
    # D-RCTP-25: the Nodes check comes before the body's; a receiver answers 400 (R-RCTP-30).
    push.refused(ctx, 400, "R-RCTP-30", "Nodes naming ghost, which the access lacks")


@scenario_case(
    "rctp/client/event-push-one-node",
    "A data-change WRITE that lists one node of its access (the one changed) is answered 200,"
    " and that node's value alone is the client's newest",
    ["R-RCTP-61", "R-RCTP-24"],
)
async def event_push_one_node(ctx: Context) -> None:
    push = await _push(ctx, one_node=True)
    ctx.expect_status(push.answer, 200, "R-RCTP-24", what="a push of one node of the access")
    push.written_back(ctx, push.pushed, "the one pushed value with the others it had")


@scenario_case(
    "rctp/client/event-push-nodes-backwards",
    "A data-change WRITE whose Nodes lists its nodes out of canonical order (its body in"
    " canonical order) is refused with 400 and not taken",
    ["R-RCTP-30", "R-RCTP-61"],
)
async def event_push_nodes_backwards(ctx: Context) -> None:
    # A client that sorts the names it is given, as a decoder of canonical bodies does, takes it.
    push = await _push(ctx, listing=_backwards)
    push.refused(ctx, 400, "R-RCTP-30", "Nodes out of canonical order")


@scenario_case(
    "rctp/client/event-push-nodes-repeated",
    "A data-change WRITE whose Nodes names its first node twice in a row (its body holding that"
    " value twice) is refused with 400 and not taken",
    ["R-RCTP-30", "R-RCTP-61"],
)
async def event_push_nodes_repeated(ctx: Context) -> None:
    # R-RCTP-30 lists each node once: a name twice in a row is still in order by `<=`, so a
    # client that checks the order alone takes it, and decodes the body it matches.
    def twice(pushed: dict[str, Value], codec: ValuesCodec[DataNode]) -> bytes:
        first = ValuesCodec(codec.nodes[:1], codec.where, codec.rule)
        return first.encode({first.names[0]: pushed[first.names[0]]}) + codec.encode(pushed)

    push = await _push(ctx, twice, listing=lambda names: [names[0], *names])
    push.refused(ctx, 400, "R-RCTP-30", "Nodes naming a node twice")


@scenario_case(
    "rctp/client/event-push-paused",
    "A data-change WRITE of the event access once the client's PAUSE of it is answered (the"
    " access ready, not playing) is refused with 455 and not taken",
    ["R-RCTP-68", "R-RCTP-61"],
)
async def event_push_paused(ctx: Context) -> None:
    # D-RCTP-14: PAUSE answered 200 leaves the access `ready`; D-RCTP-26: a server WRITE of an
    # access not playing on the client's side is 455. Step 5 pauses the access before its WRITE.
    push = await _push(ctx, paused=True)
    ctx.expect_status(push.answer, 455, "R-RCTP-68", what="a push of the paused access")
    if push.written_after_answer:
        push.written_back(ctx, push.before, NOT_TAKEN)
    else:
        ctx.cannot_check(
            "that the refused push was not taken (R-RCTP-61): the client's WRITE after its PAUSE"
            " came before its answer to the push, so it holds the values from before either way"
        )


@dataclass
class _Push:
    """What step 5 gave with a data-change WRITE: the values the client had before it and those
    pushed, its answer, and the WRITE of the access that followed the client's PAUSE."""

    before: dict[str, Value]
    pushed: dict[str, Value]
    answer: Response
    after: Seen
    codec: ValuesCodec[DataNode]
    #: Whether that WRITE came after the client's answer to the push (so it was sent knowing it).
    written_after_answer: bool

    def written_back(self, ctx: Context, values: dict[str, Value], meaning: str) -> None:
        body = self.codec.encode(values)
        found = self.after.request.body
        ctx.expect(found == body, f"{meaning}: {body.hex(' ')}", found.hex(" "), "R-RCTP-61")

    def refused(self, ctx: Context, status: int, requirement: str, what: str) -> None:
        """The push answered `status` (`what`: what is wrong with it), and not taken."""
        ctx.expect_status(self.answer, status, requirement, what=what)
        self.written_back(ctx, self.before, NOT_TAKEN)


def _backwards(names: list[str]) -> list[str]:
    return names[::-1]


def _canonical(pushed: dict[str, Value], codec: ValuesCodec[DataNode]) -> bytes:
    """A push's body as its Nodes list it: the values in canonical order (D-RCTP-20)."""
    return codec.encode(pushed)


async def _push(
    ctx: Context,
    body: Callable[[dict[str, Value], ValuesCodec[DataNode]], bytes] = _canonical,
    listing: Listing = list,
    one_node: bool = False,
    paused: bool = False,
) -> _Push:
    """Step 5 with a data-change WRITE of the event access once it plays (once the client's
    PAUSE of it is answered, if `paused`), its body made by `body` from values at the high edge
    of each node it carries (every writable node, or with `one_node` the middle one in canonical
    order), its `Nodes` made by `listing` from their names; the scenario is then run to its
    BYE."""
    server, access, _ = await until_event_go(ctx)
    codec = ValuesCodec(access.writable(), access.path, "R-RCTP-28")
    before = {n.name: server.values[n.path] for n in codec.nodes}
    listed = codec
    if one_node:  # D-RCTP-27: a push lists the nodes changed, and only those
        listed = ValuesCodec([codec.nodes[len(codec.nodes) // 2]], access.path, "R-RCTP-28")
    pushed = {**before, **{n.name: edge(n, high=True) for n in listed.nodes}}
    values = pushed if listed is codec else {name: pushed[name] for name in listed.names}
    write = server.push(access, listing(list(listed.names)), body(values, listed))
    since = len(server.seen)
    if paused:
        await _after_pause(server, access, write)
    else:
        await server.probe.send(write)
    # Mid-scenario the client's own CSeq is well past the server's: an answer numbered by the
    # client's counter fails as the probe matches it to the WRITE's (R-RCTP-3).
    answer = await server.answer()
    # The client's WRITE after its PAUSE may have come while the played server awaited the answer.
    early = next((s for s in server.seen[since:] if s.names("WRITE", access.path)), None)
    after = early or await server.reach("WRITE", access.path)
    if after is None:
        raise Inconclusive(f"the client did not WRITE {access.path} after its PAUSE (step 5)")
    await server.reach("BYE")
    return _Push(before, pushed, answer, after, codec, written_after_answer=early is None)


async def _after_pause(server: PlayedServer, access: AccessNode, write: bytes) -> None:
    """Send `write` in the segment of the answer to the client's PAUSE of `access` (step 5): a
    client that reads its segments whole takes the push before it builds its WRITE of the
    access, which then shows whether it took it."""

    def own(request: Request) -> bytes | None:
        if not (request.method == "PAUSE" and path_of(request) == access.path):
            return None
        return server.probe.response_bytes(request) + write

    server.own = own
    pause = await server.reach("PAUSE", access.path)
    server.own = None
    if pause is None:
        raise Inconclusive(f"the client did not PAUSE {access.path} (D-RCTP-31 step 5)")
