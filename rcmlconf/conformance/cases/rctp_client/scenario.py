"""rctp/client, the scenario's requests: what an RCTP/2.0 client under test sends while it runs
D-RCTP-31's scenario against the server the harness plays (`probes.played`): its numbering, its
session, its targets, and the values it reads and writes, of every data type of the harness's
robot (R-RCTP-3, R-RCTP-4, R-RCTP-19, R-RCTP-30, R-RCTP-60, R-RCML-29, R-RCML-30); the server's
pushes are judged in `pushes`."""

from __future__ import annotations

import math
import struct
from collections.abc import Callable

from rcmlconf.conformance.cases.rctp_client.answers import client_case
from rcmlconf.conformance.context import Context
from rcmlconf.conformance.flaws import Flaw, flawed
from rcmlconf.conformance.probes.clients import Served, case_path
from rcmlconf.conformance.probes.held import longest_hold
from rcmlconf.conformance.probes.played import (
    SCENARIO_TIME,
    Own,
    PlayedServer,
    Seen,
    path_of,
    played,
)
from rcmlconf.conformance.registry import CaseFunction
from rcmlconf.conformance.verdicts import Failed, Inconclusive
from rcmlconf.rcml.model import AccessNode, AccessType, DataNode, Permission
from rcmlconf.rctp.bodies import ValuesCodec
from rcmlconf.rctp.fields import format_nodes
from rcmlconf.rctp.messages import Request
from rcmlconf.rctp.targets import format_target
from rcmlconf.values import Kind, Scalar, Value
from rcmlconf.values.binary import encode_value
from rcmlconf.values.shown import value_text
from rcmlconf.wording import plural

#: The fewest requests a run of the scenario makes on the harness's robot, less a margin.
ENOUGH_REQUESTS = 10
#: The session timeout refresh-connect's CONNECT answer gives (D-RCTP-11 sets no least one): step
#: 5's 1 s, in which the scenario asks nothing, is then as long as the timeout itself, so a client
#: that refreshes before its session could lapse does it there.
REFRESH_TIMEOUT = 1
#: R-RCTP-23: how long the sender of a BYE waits for its answer before it closes.
BYE_WAIT = 5.0
_FLOAT32_MAX = struct.unpack(">f", b"\x7f\x7f\xff\xff")[0]


def scenario_case(
    id: str, purpose: str, requirements: list[str], served: Served | None = None
) -> Callable[[CaseFunction], CaseFunction]:
    """A case that runs the client's whole scenario: it takes longer than a plain client case."""
    return client_case(id, purpose, requirements, timeout=SCENARIO_TIME, served=served)


async def whole_run(ctx: Context) -> PlayedServer:
    """The client's scenario run to its BYE (or its end) against the played server."""
    server = await played(ctx)
    await server.reach("BYE")
    return server


def normal_nodes(ctx: Context, permission: Permission) -> list[DataNode]:
    """The data nodes of normal accesses with `permission`, in document order (D-RCTP-31)."""
    found = []
    for node in ctx.robot.data_nodes():
        access = ctx.robot.node(node.path.rsplit("/", 1)[0])
        normal = isinstance(access, AccessNode) and access.type is AccessType.NORMAL
        if normal and permission in node.permission:
            found.append(node)
    return found


def edge(node: DataNode, high: bool) -> Value:
    """A value of the node at an edge of its type (and range): what a codec gets wrong first."""
    base = node.type.base
    item: Scalar
    if base.kind is Kind.INTEGER:
        low_end = base.low if node.minimum is None else int(node.minimum)
        high_end = base.high if node.maximum is None else int(node.maximum)
        item = high_end if high else low_end
    elif base.kind is Kind.FLOAT:
        largest = _FLOAT32_MAX if base.name == "float32" else 1.7976931348623157e308
        smallest = -math.ulp(0.0) if base.name == "float64" else -1.5
        bound = node.maximum if high else node.minimum  # D-RCML-12: within the node's range
        item = float(bound) if bound is not None else largest if high else smallest
    elif base.kind is Kind.BOOL:
        item = high
    elif base.kind is Kind.STRING:
        size = node.type.size
        item = "é" * (size // 2) if high else "A\u00a0z"[: max(1, min(size, 3))]
    else:
        item = b"\xff" * node.type.size if high else b"\x00"
    return tuple([item] * node.type.count) if node.type.is_array else item


def wrote(server: PlayedServer, node: DataNode) -> list[Seen]:
    return [s for s in server.requests("WRITE") if s.path == node.path]


# -- numbering, session, targets -----------------------------------------------------------------


@scenario_case(
    "rctp/client/cseq-numbering",
    "Every request of the scenario carries CSeq, numbered 1, 2, 3, ... in the order sent, and"
    " the version RCTP/2.0",
    ["R-RCTP-4", "R-RCTP-3", "R-RCTP-2"],
)
async def cseq_numbering(ctx: Context) -> None:
    server = await whole_run(ctx)
    seen = server.requests()
    if len(seen) < ENOUGH_REQUESTS:
        made = plural(len(seen), "request")
        raise Inconclusive(f"the client made {made}; the scenario makes more")
    for number, one in enumerate(seen, 1):
        cseq = one.request.headers.get("CSeq")
        ctx.expect(
            cseq is not None, "CSeq in every request", f"none in request {number}", "R-RCTP-3"
        )
        ctx.expect(
            cseq == str(number),
            f"CSeq: {number} in request {number} ({one.request.method})",
            f"CSeq: {cseq}",
            "R-RCTP-4",
        )
        # The reader takes any RCTP/x.y (a server answers another 505): each is checked here.
        version = one.request.version
        ctx.expect(version == "RCTP/2.0", f"RCTP/2.0 in request {number}", version, "R-RCTP-2")


@scenario_case(
    "rctp/client/session-in-every-request",
    "Every request after CONNECT names the session CONNECT opened",
    ["R-RCTP-19"],
)
async def session_in_every_request(ctx: Context) -> None:
    server = await whole_run(ctx)
    later = server.requests()[1:]
    if len(later) < ENOUGH_REQUESTS - 1:
        made = plural(len(later) + 1, "request")
        raise Inconclusive(f"the client made {made}; the scenario makes more")
    for one in later:
        _names_session(ctx, server, one)


def _names_session(ctx: Context, server: PlayedServer, one: Seen) -> None:
    """R-RCTP-19: a request after CONNECT names the session CONNECT opened."""
    found = one.request.headers.get("Session")
    ctx.expect(
        found == server.probe.session,
        f"Session: {server.probe.session} in {one.request.method} {one.request.target}",
        f"Session: {found}",
        "R-RCTP-19",
    )


@scenario_case(
    "rctp/client/targets-and-bye",
    "CONNECT names the case's site path, BYE names *, and nothing follows the client's BYE",
    ["R-RCTP-60", "R-RCTP-23"],
)
async def targets_and_bye(ctx: Context) -> None:
    server = await played(ctx)
    first = await server.serve(until=lambda _: True)
    if first is None:
        raise Inconclusive("the client sent no request")
    site = case_path(ctx.case.id)
    ctx.expect(
        first.request.method == "CONNECT" and first.path == site,
        f"CONNECT {site}",
        f"{first.request.method} {first.request.target}",
        "R-RCTP-60",
    )
    bye = await server.reach("BYE")
    if bye is None:
        raise Inconclusive("the client sent no BYE (D-RCTP-31 step 8)")
    ctx.expect(bye.request.target == "*", "BYE *", f"BYE {bye.request.target}", "R-RCTP-60")
    after = await server.probe.outcome(5.0 * ctx.scale)
    ctx.expect(
        after == "closed",
        "the connection closed after the BYE was answered, nothing sent",
        after,
        "R-RCTP-60" if after.startswith("it sent") else "R-RCTP-23",
    )


@scenario_case(
    "rctp/client/bye-unanswered-closes",
    f"The client's BYE left unanswered: it closes the connection {BYE_WAIT:g} s later (D-RCTP-33:"
    " between 4.5 s and 6.5 s after the BYE), sending nothing more",
    ["R-RCTP-23"],
)
async def bye_unanswered_closes(ctx: Context) -> None:
    server = await played(ctx)

    # The SETUPs refused leave steps 5 and 6 out (D-RCTP-31: no GO after a failed SETUP), so
    # that the BYE comes within a second or so and the case has the time to wait for the close.
    def own(request: Request) -> bytes | None:
        if request.method == "SETUP":
            return server.probe.response_bytes(request, 503, "Service Unavailable")
        return b"" if request.method == "BYE" else None

    server.own = own
    bye = await server.reach("BYE")
    if bye is None:
        raise Inconclusive("the client sent no BYE (D-RCTP-31 step 8)")
    after = await server.probe.outcome(BYE_WAIT + 1.5 * ctx.scale)
    waited = server.loop.time() - bye.at
    within = after == "closed" and waited >= BYE_WAIT - 0.5
    # Read off the harness's clock: a loop held when the BYE came makes the wait look short, one
    # held at its end long. Only a hold as long as the bound's least slack, half a second, can
    # explain a miss (the holds `expect(timing=True)` excuses are those of tighter checks).
    held = longest_hold(ctx, ctx.started)
    if not within and not after.startswith("it sent") and held >= 0.5 * ctx.scale:
        raise Inconclusive(
            f"the connection {after} after {waited:.2f} s, but the harness's event loop was held"
            f" {held:.2f} s during the case"
        )
    ctx.expect(
        within,
        f"the connection closed {BYE_WAIT:g} s after the unanswered BYE, nothing sent",
        f"{after} after {waited:.2f} s",
        "R-RCTP-60" if after.startswith("it sent") else "R-RCTP-23",
    )


@scenario_case(
    "rctp/client/answer-to-nothing",
    "The client closes the connection on an answer when none of its requests is unanswered (its"
    " GO of the event access answered again, in step 5's quiet second)",
    ["R-RCTP-12"],
)
async def answer_to_nothing(ctx: Context) -> None:
    server, access, go = await until_event_go(ctx)
    # D-RCTP-10: an answer to no outstanding request cannot be answered; the receiver closes
    # (within 1 s, D-RCTP-31). The client asks nothing for a second after its GO (step 5).
    await server.probe.send(server.probe.response_bytes(go.request))
    after = await server.probe.outcome(ctx.wait)
    ctx.expect(
        after == "closed",
        f"the connection closed: a second answer to GO {access.path} answers nothing",
        after,
        "R-RCTP-12",
    )


@scenario_case(
    "rctp/client/answer-and-request-together",
    "The answer to the client's GO of the event access and a data-change WRITE of it in one"
    " segment are both read: the WRITE is answered 200",
    ["R-RCTP-13"],
)
async def answer_and_request_together(ctx: Context) -> None:
    def together(server: PlayedServer, access: AccessNode) -> Own:
        codec = ValuesCodec(access.writable(), access.path, "R-RCTP-28")
        pushed = codec.encode({n.name: edge(n, high=True) for n in codec.nodes})
        nodes = [("Nodes", format_nodes(codec.names))]

        def own(request: Request) -> bytes | None:
            if request.method != "GO" or path_of(request) != access.path:
                return None
            # A client that reads one message a read, and drops the rest, loses the WRITE.
            write = server.probe.request_bytes("WRITE", format_target(access.path), nodes, pushed)
            return server.probe.response_bytes(request) + write

        return own

    server, _, _ = await until_event_go(ctx, together)
    try:
        answer = await server.answer()
    except Failed as failed:  # an answer that never comes: the WRITE was not read
        raise Failed(
            "R-RCTP-13", "an answer to the WRITE in the GO answer's segment", failed.actual
        ) from None
    ctx.expect_status(answer, 200, "R-RCTP-13", what="the WRITE after the GO's answer")
    await server.reach("BYE")


@scenario_case(
    "rctp/client/refresh-connect",
    f"With a session timeout of {REFRESH_TIMEOUT} s, the CONNECTs that refresh the session name"
    " the case's site path, as the first did, and carry the session",
    ["R-RCTP-60", "R-RCTP-19"],
)
async def refresh_connect(ctx: Context) -> None:
    server = await played(ctx)
    server.session_timeout = REFRESH_TIMEOUT
    await server.reach("BYE")
    refreshes = server.requests("CONNECT")[1:]
    if not refreshes:
        raise Inconclusive(
            f"the client sent no CONNECT to refresh its session of {REFRESH_TIMEOUT} s: D-RCTP-11"
            " has a client with nothing else to say refresh, but the scenario's gaps are short"
            " and its DATA keeps the session alive (D-RCTP-31 obliges no refresh)"
        )
    site = case_path(ctx.case.id)
    for one in refreshes:
        ctx.expect(
            one.path == site,
            f"CONNECT {site}: a refresh names the site path (D-RCTP-11)",
            f"CONNECT {one.request.target}",
            "R-RCTP-60",
        )
        _names_session(ctx, server, one)


# -- values of every type ------------------------------------------------------------------------


async def _round_trip(
    ctx: Context, high: bool, requirement: str = "R-RCML-30", shouting: bool = False
) -> PlayedServer:
    """Step 4: each normal node written with the value its READ gave (R-RCML-30 both ways; with
    `shouting`, the answers' tokens in capitals, R-RCTP-59)."""
    server = await played(ctx)
    server.shouting = shouting
    nodes = normal_nodes(ctx, Permission.READ | Permission.WRITE)
    if not nodes:
        raise Inconclusive("the robot has no readable and writable data node of a normal access")
    for node in nodes:
        server.values[node.path] = edge(node, high)
    await server.reach("BYE")
    if shouting:
        after = [s.request.method for s in server.requests()[1:]]
        ctx.expect(bool(after), "requests after CONNECT", "none", requirement)
    if not server.requests("WRITE"):
        raise Inconclusive("the client wrote nothing (D-RCTP-31 step 4)")
    for node in nodes:
        if node.path not in server.read_paths():
            continue  # the client did not READ it: nothing to write back
        bodies = [s.request.body for s in wrote(server, node)]
        value = edge(node, high)
        expected = encode_value(node.type, value)
        ctx.expect(
            bool(bodies),
            f"a WRITE of {node.path} with the {node.type} value READ gave,"
            f" {value_text(node.type, value)}",
            "none: the client did not take the value it read",
            requirement,
        )
        ctx.expect(
            bodies[0] == expected,
            f"WRITE {node.path} body {expected.hex(' ')}",
            f"{bodies[0].hex(' ')}",
            requirement,
        )
    return server


@scenario_case(
    "rctp/client/values-high",
    "Values of every type at the top of their range, read and written back exactly",
    ["R-RCML-30"],
)
async def values_high(ctx: Context) -> None:
    await _round_trip(ctx, high=True)


@scenario_case(
    "rctp/client/values-low",
    "Values of every type at the bottom of their range, read and written back exactly",
    ["R-RCML-30"],
)
async def values_low(ctx: Context) -> None:
    await _round_trip(ctx, high=False)


@scenario_case(
    "rctp/client/tokens-any-case",
    "Answers that spell the media type, Session's timeout, and Transport's udp, parameter names"
    " and mode in capitals are taken as in lower case: values read are written back, the"
    " stream plays",
    ["R-RCTP-59"],
)
async def tokens_any_case(ctx: Context) -> None:
    server = await _round_trip(ctx, high=True, requirement="R-RCTP-59", shouting=True)
    setups = [s for s in server.requests("SETUP") if s.status == 200]
    if not setups or server.stream is None:
        raise Inconclusive("the client set up no stream (D-RCTP-31 step 6)")
    ctx.expect(
        bool(server.stream.data()),
        "DATA of the stream its SETUP answer set up (Transport: UDP;CLIENT_PORT=...;MODE=BOTH)",
        "none",
        "R-RCTP-59",
    )


@scenario_case(
    "rctp/client/body-fields",
    "Every request of the client's with a body carries Content-Length and the Content-Type"
    " application/rctp-values, and none Transfer-Encoding",
    ["R-RCTP-6", "R-RCTP-7"],
)
async def body_fields(ctx: Context) -> None:
    server = await whole_run(ctx)
    with_body = [s.request for s in server.requests() if s.request.body]
    if not with_body:
        raise Inconclusive("the client sent no request with a body (D-RCTP-31 step 4)")
    for request in with_body:
        what = f"{request.method} {request.target}"
        headers = request.headers
        ctx.expect(
            headers.get("Content-Length") is not None,
            f"Content-Length in {what}",
            "none",
            "R-RCTP-6",
        )
        media = (headers.get("Content-Type") or "").split(";")[0].strip().lower()
        ctx.expect(
            media == "application/rctp-values",
            f"Content-Type: application/rctp-values in {what}",
            f"Content-Type: {headers.get('Content-Type')}",
            "R-RCTP-6",
        )
        ctx.expect(
            headers.get("Transfer-Encoding") is None,
            f"no Transfer-Encoding in {what}",
            f"Transfer-Encoding: {headers.get('Transfer-Encoding')}",
            "R-RCTP-7",
        )


_FLAWS = (Flaw.BOOL_BYTE, Flaw.OVER_SIZE, Flaw.NOT_UTF8, Flaw.PAST_END, Flaw.ITEM_COUNT)


@scenario_case(
    "rctp/client/malformed-read",
    "READ answers whose value is malformed (a bool byte of 2, a string over its size or not"
    " UTF-8, a length past the end, an array short) are not taken: the node is not written",
    ["R-RCML-30"],
)
async def malformed_read(ctx: Context) -> None:
    server = await played(ctx)
    bad: dict[str, tuple[bytes, str]] = {}
    for node in normal_nodes(ctx, Permission.READ | Permission.WRITE):
        for flaw in _FLAWS:
            found = flawed(node, flaw)
            if found and node.path not in bad:
                bad[node.path] = (found[0].data, found[0].what)
    if not bad:
        raise Inconclusive("the robot has no node whose value can be malformed")

    def own(request: Request) -> bytes | None:
        path = path_of(request)
        if request.method != "READ" or path not in bad:
            return None
        fields = [("Content-Type", "application/rctp-values")]
        return server.probe.response_bytes(request, 200, "OK", fields, bad[path][0])

    server.own = own
    await server.reach("BYE")
    read = {s.path for s in server.requests("READ")}
    if not read & bad.keys():
        raise Inconclusive("the client read none of the nodes answered malformed")
    for path, (_, what) in bad.items():
        if path not in read:
            continue
        taken = [s for s in server.requests("WRITE") if s.path == path]
        ctx.expect(
            not taken,
            f"no WRITE of {path}: its READ answer held {what}",
            f"WRITE {path} with {taken[0].request.body.hex(' ') if taken else ''}",
            "R-RCML-30",
        )


# -- event accesses ------------------------------------------------------------------------------


def event_access(ctx: Context) -> AccessNode:
    return ctx.access(AccessType.EVENT, Permission.READ | Permission.WRITE)


@scenario_case(
    "rctp/client/event-write-nodes",
    "An event access's WRITE lists its writable nodes in canonical order, the body their values"
    " in that order",
    ["R-RCTP-30", "R-RCML-29", "R-RCML-30"],
)
async def event_write_nodes(ctx: Context) -> None:
    access = event_access(ctx)
    server = await played(ctx)
    for node in access.data:
        server.values[node.path] = edge(node, high=True)
    await server.reach("BYE")
    writes = [s for s in server.requests("WRITE") if s.path == access.path]
    if not writes:
        raise Inconclusive(f"the client did not WRITE {access.path} (D-RCTP-31 step 4)")
    codec = ValuesCodec(access.writable(), access.path, "R-RCTP-28")
    nodes = format_nodes(codec.names)
    first = writes[0].request
    listed = first.headers.get("Nodes")
    ctx.expect(listed == nodes, f"Nodes: {nodes}", f"Nodes: {listed}", "R-RCTP-30")
    body = codec.encode({n.name: server.values[n.path] for n in codec.nodes})
    ctx.expect(first.body == body, f"body {body.hex(' ')}", first.body.hex(" "), "R-RCML-30")


async def until_event_go(
    ctx: Context, own: Callable[[PlayedServer, AccessNode], Own] | None = None
) -> tuple[PlayedServer, AccessNode, Seen]:
    """The scenario up to the GO of the event access of step 5, answered (by the answers `own`
    makes of the played server and the access, until then, if given): the played server, the
    access and the GO."""
    access = event_access(ctx)
    server = await played(ctx)
    server.own = own(server, access) if own is not None else None
    go = await server.reach("GO", access.path)
    server.own = None
    if go is None:
        raise Inconclusive(f"the client did not GO {access.path} (D-RCTP-31 step 5)")
    return server, access, go
