"""rctp/client: an RCTP/2.0 client under test, the harness playing its server (`--role client`):
how it answers the server's WRITE, STOP and BYE and what it does with broken answers
(specs/rctp-2.0.md D-RCTP-5, D-RCTP-12, D-RCTP-26; R-RCTP-1 to R-RCTP-24)."""

from __future__ import annotations

from collections.abc import Callable

from rcmlconf.conformance.context import Context
from rcmlconf.conformance.probes.clients import Served, case_path
from rcmlconf.conformance.probes.control import ControlProbe
from rcmlconf.conformance.registry import CaseFunction, case
from rcmlconf.conformance.roles import Role
from rcmlconf.rcml.model import AccessType
from rcmlconf.rctp.messages import Response
from rcmlconf.rctp.targets import format_target


def client_case(
    id: str,
    purpose: str,
    requirements: list[str],
    timeout: float = 5.0,
    served: Served | None = None,
) -> Callable[[CaseFunction], CaseFunction]:
    """A client case: one connection at a time, so never two at once."""
    return case(
        id, purpose, requirements, role=Role.CLIENT, serial=True, timeout=timeout, served=served
    )


async def answer_to(ctx: Context, probe: ControlProbe, data: bytes) -> Response:
    """Send one of the server's requests as `data`; the client's answer. Requests the client
    sends meanwhile are its right (D-RCTP-6): the probe answers them as a busy server would."""
    await probe.send(data)
    return await probe.response(closed="R-RCTP-24")


def event_path(ctx: Context) -> str:
    return format_target(ctx.access(AccessType.EVENT).path)


@client_case(
    "rctp/client/connect-first",
    "The client's first request is CONNECT of the site path, RCTP/2.0, CSeq 1, its lines ending"
    " in CRLF",
    ["R-RCTP-2", "R-RCTP-4", "R-RCTP-60", "R-RCTP-1"],
)
async def connect_first(ctx: Context) -> None:
    probe = await ctx.client()
    request = await probe.next_request(requirement="R-RCTP-4")
    ctx.expect(request.method == "CONNECT", "CONNECT", request.method, "R-RCTP-4")
    site = case_path(ctx.case.id)  # D-RCTP-31: the case's URL is the site
    ctx.expect(request.target == site, f"CONNECT {site}", f"CONNECT {request.target}", "R-RCTP-60")
    ctx.expect(request.version == "RCTP/2.0", "RCTP/2.0", request.version, "R-RCTP-2")
    cseq = request.headers.get("CSeq")
    ctx.expect(cseq == "1", "CSeq: 1", f"CSeq: {cseq}", "R-RCTP-4")


@client_case(
    "rctp/client/answers-bye",
    "The client answers the server's BYE with 200 RCTP/2.0 and its CSeq",
    ["R-RCTP-23", "R-RCTP-3", "R-RCTP-2"],
)
async def answers_bye(ctx: Context) -> None:
    probe, _ = await ctx.client_session()
    answer = await answer_to(ctx, probe, probe.request_bytes("BYE", "*", [("Reason", "shutdown")]))
    ctx.expect_status(answer, 200, "R-RCTP-23")
    # Its CSeq, 1: the probe matches every answer to its request's (R-RCTP-3).
    # The reader takes any RCTP/x.y (a receiver answers another version 505): the status line's
    # own is checked here. (R-RCTP-19 binds requests: the answer's Session is not checked.)
    ctx.expect(answer.version == "RCTP/2.0", "RCTP/2.0", answer.version, "R-RCTP-2")


@client_case(
    "rctp/client/stop-not-set-up",
    "The client answers a server STOP of an access it never set up with 455",
    ["R-RCTP-68"],
)
async def stop_not_set_up(ctx: Context) -> None:
    path = event_path(ctx)
    probe, _ = await ctx.client_session()
    answer = await answer_to(ctx, probe, probe.request_bytes("STOP", path, [("Reason", "test")]))
    ctx.expect_status(answer, 455, "R-RCTP-68")


@client_case(
    "rctp/client/write-not-playing",
    "The client answers a server WRITE of an event access not playing on its side with 455",
    ["R-RCTP-68"],
)
async def write_not_playing(ctx: Context) -> None:
    path = event_path(ctx)
    probe, _ = await ctx.client_session()
    answer = await answer_to(ctx, probe, probe.request_bytes("WRITE", path, body=b"\x00"))
    ctx.expect_status(answer, 455, "R-RCTP-68")


@client_case(
    "rctp/client/wrong-session",
    "The client answers a server request naming another session with 454",
    ["R-RCTP-19"],
)
async def wrong_session(ctx: Context) -> None:
    probe, _ = await ctx.client_session()
    request = probe.request_bytes("BYE", "*", [("Session", "not-this-session-0")])
    ctx.expect_status(await answer_to(ctx, probe, request), 454)


@client_case(
    "rctp/client/unknown-method",
    "The client answers a server request with an unknown method with 501",
    ["R-RCTP-9"],
)
async def unknown_method(ctx: Context) -> None:
    probe, _ = await ctx.client_session()
    ctx.expect_status(await answer_to(ctx, probe, probe.request_bytes("FROBNICATE", "*")), 501)


@client_case(
    "rctp/client/wrong-version",
    "The client answers a server request of another version with 505, and answers the next"
    " request on the same connection",
    ["R-RCTP-10"],
)
async def wrong_version(ctx: Context) -> None:
    probe, _ = await ctx.client_session()
    request = probe.request_bytes("BYE", "*").replace(b"RCTP/2.0", b"RCTP/3.0", 1)
    ctx.expect_status(await answer_to(ctx, probe, request), 505)
    # R-RCTP-10 keeps the connection open (D-RCTP-10: the request was framed).
    await answer_to(ctx, probe, probe.request_bytes("BYE", "*", [("Reason", "shutdown")]))


@client_case(
    "rctp/client/missing-cseq",
    "The client answers a server request without CSeq with 400",
    ["R-RCTP-11"],
)
async def missing_cseq(ctx: Context) -> None:
    probe, _ = await ctx.client_session()
    request = f"BYE * RCTP/2.0\r\nSession: {probe.session}\r\n\r\n".encode()
    answer = await answer_to(ctx, probe, request)
    ctx.expect_status(answer, 400)
    # D-RCTP-10: without CSeq, as the probe matches answers (there is none to echo; R-RCTP-3).


@client_case(
    "rctp/client/pipelined",
    "Two server requests in one segment are answered in order, each with its CSeq",
    ["R-RCTP-13", "R-RCTP-5", "R-RCTP-68"],
)
async def pipelined(ctx: Context) -> None:
    path = event_path(ctx)
    probe, _ = await ctx.client_session()
    stop = probe.request_bytes("STOP", path, [("Reason", "test")])
    bye = probe.request_bytes("BYE", "*", [("Reason", "shutdown")])
    await probe.send(stop + bye)
    # The STOP names an access never set up (R-RCTP-68); the BYE's 200 shows it was read. Each
    # answer's CSeq is its request's, in order (R-RCTP-5), as the probe matches them.
    for status, requirement in ((455, "R-RCTP-68"), (200, "R-RCTP-13")):
        answer = await probe.response(closed="R-RCTP-24", cseq_rule="R-RCTP-5")
        ctx.expect_status(answer, status, requirement)


@client_case(
    "rctp/client/split-answer",
    "The client takes a CONNECT answer written one byte a segment, and goes on",
    ["R-RCTP-13"],
)
async def split_answer(ctx: Context) -> None:
    probe = await ctx.client()
    connect = await probe.next_request()
    probe.session = "split0123456789"
    for byte in probe.response_bytes(connect, fields=[("Session", f"{probe.session};timeout=60")]):
        await probe.send(bytes([byte]))
    answer = await answer_to(ctx, probe, probe.request_bytes("BYE", "*", [("Reason", "shutdown")]))
    ctx.expect_status(answer, 200)


@client_case(
    "rctp/client/unknown-field",
    "The client ignores a header field it does not know in the CONNECT answer",
    ["R-RCTP-14"],
)
async def unknown_field(ctx: Context) -> None:
    probe = await ctx.client()
    connect = await probe.next_request()
    probe.session = "fields0123456789"
    fields = [("Session", f"{probe.session};timeout=60"), ("X-Rcmlconf-Probe", "ignore me")]
    await probe.answer(connect, fields=fields)
    answer = await answer_to(ctx, probe, probe.request_bytes("BYE", "*", [("Reason", "shutdown")]))
    ctx.expect_status(answer, 200)


@client_case(
    "rctp/client/bad-target",
    "The client answers a server request whose target is neither *, / nor a node path (no"
    " leading /, a segment that is no XML Name) with 400",
    ["R-RCTP-15"],
)
async def bad_target(ctx: Context) -> None:
    probe, _ = await ctx.client_session()
    # D-RCTP-7: a node path begins with `/`, and each segment decodes to an XML Name; a STOP is
    # what a client would answer otherwise (455, R-RCTP-68).
    for target in (event_path(ctx).lstrip("/"), "/9lives"):
        request = probe.request_bytes("STOP", target, [("Reason", "test")])
        answer = await answer_to(ctx, probe, request)
        ctx.expect_status(answer, 400, "R-RCTP-15", what=f"STOP {target}")


#: Answers to CONNECT that cannot be framed (D-RCTP-4, D-RCTP-10), by case.
_UNFRAMEABLE = {
    "unframeable-answer": ("a status code in words", b"RCTP/2.0 two hundred OK\r\nCSeq: 1\r\n"),
    "bare-lf-answer": ("lines ending in a bare LF", b"RCTP/2.0 200 OK\nCSeq: 1\nSession: {s}\n"),
    "rtsp-answer": ("another protocol's status line", b"RTSP/1.0 200 OK\r\nCSeq: 1\r\n"),
    "bad-length-answer": (
        "a Content-Length that is not a number",
        b"RCTP/2.0 200 OK\r\nCSeq: 1\r\nSession: {s}\r\nContent-Length: 1x\r\n",
    ),
    "chunked-answer": (
        "Transfer-Encoding, which RCTP/2.0 does not use",
        b"RCTP/2.0 200 OK\r\nCSeq: 1\r\nSession: {s}\r\nTransfer-Encoding: chunked\r\n",
    ),
}


def _unframeable(name: str, what: str, head: bytes) -> None:
    @client_case(
        f"rctp/client/{name}",
        f"The client closes the connection on an answer to CONNECT with {what}",
        ["R-RCTP-12"],
    )
    async def closes(ctx: Context) -> None:
        probe = await ctx.client()
        await probe.next_request()
        await probe.send(head.replace(b"{s}", b"frame0123456789;timeout=60") + b"\r\n")
        ctx.expect(await probe.closes(), "the connection closed", "it stayed open")


for _name, (_what, _head) in _UNFRAMEABLE.items():
    _unframeable(_name, _what, _head)


@client_case(
    "rctp/client/answer-of-another-request",
    "The client closes the connection on an answer whose CSeq is not its request's",
    ["R-RCTP-12"],
)
async def answer_of_another_request(ctx: Context) -> None:
    probe = await ctx.client()
    await probe.next_request()
    await probe.send(b"RCTP/2.0 200 OK\r\nCSeq: 7\r\nSession: other0123456789;timeout=60\r\n\r\n")
    ctx.expect(await probe.closes(), "the connection closed", "it stayed open")
