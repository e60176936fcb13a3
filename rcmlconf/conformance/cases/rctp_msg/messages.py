"""rctp/msg: the message grammar and what a server does with bad messages (specs/rctp-2.0.md
§2, D-RCTP-4 to D-RCTP-10, R-RCTP-1 to R-RCTP-16)."""

from __future__ import annotations

from rcmlconf.conformance.cases.rctp_msg.grammar import (
    HEADER_SECTION,
    _broken_connect,
    _filler,
    _refused_and_closed,
)
from rcmlconf.conformance.context import Context, expect_answer
from rcmlconf.conformance.probes.control import ControlProbe
from rcmlconf.conformance.registry import case
from rcmlconf.rctp.messages import VERSION


async def still_open(ctx: Context, probe: ControlProbe) -> None:
    """The connection still takes requests: a CONNECT refresh is answered, whatever the status
    (rctp/session/connect-refresh checks the status)."""
    await probe.send(probe.request_bytes("CONNECT", ctx.target.site_path))
    found = await probe.message()
    ctx.expect(found is not None, "the connection kept open", "it was closed")


@case(
    "rctp/msg/connect",
    "CONNECT to the site path is answered 200 with CRLF lines, RCTP/2.0 and the request's CSeq",
    ["R-RCTP-2", "R-RCTP-3"],
)
async def connect(ctx: Context) -> None:
    probe = await ctx.control()
    answer = await probe.connect(ctx.target.site_path)
    ctx.expect_status(answer, 200)
    ctx.expect(answer.version == VERSION, VERSION, answer.version, "R-RCTP-2")
    # Its CSeq: the probe matches every answer to its request's (R-RCTP-3).


@case(
    "rctp/msg/unknown-method",
    "A well-framed request with an unknown method is answered 501 and the connection stays open",
    ["R-RCTP-9"],
)
async def unknown_method(ctx: Context) -> None:
    probe = await ctx.session()
    answer = await probe.request("FROBNICATE", "/")
    ctx.expect_status(answer, 501)
    await still_open(ctx, probe)


@case(
    "rctp/msg/wrong-version",
    "A request with another version than RCTP/2.0 (RCTP/1.0, and rctp/2.0: the version is"
    " case-sensitive) is answered 505 and the connection stays open",
    ["R-RCTP-10"],
)
async def wrong_version(ctx: Context) -> None:
    probe = await ctx.session()
    # D-RCTP-30: the version is compared as written, so `rctp/2.0` is another version, not a
    # line that fails to parse (400) nor RCTP/2.0 in other letters (200).
    for cseq, version in enumerate(("RCTP/1.0", "rctp/2.0"), start=2):
        line = f"CONNECT {ctx.target.site_path} {version}"
        await probe.send(f"{line}\r\nCSeq: {cseq}\r\n\r\n".encode())
        expect_answer(ctx, await probe.response(), 505, line)
        probe.cseq = cseq
    await still_open(ctx, probe)


@case(
    "rctp/msg/missing-cseq",
    "A request without CSeq is answered 400",
    ["R-RCTP-11"],
)
async def missing_cseq(ctx: Context) -> None:
    probe = await ctx.control()
    await probe.send(f"CONNECT {ctx.target.site_path} RCTP/2.0\r\n\r\n".encode())
    ctx.expect_status(await probe.response(), 400)


@case(
    "rctp/msg/split-segments",
    "A request written one byte a segment is answered as if written whole",
    ["R-RCTP-13"],
)
async def split_segments(ctx: Context) -> None:
    probe = await ctx.control()
    for byte in probe.request_bytes("CONNECT", ctx.target.site_path):
        await probe.send(bytes([byte]))
    ctx.expect_status(await probe.response(), 200)


@case(
    "rctp/msg/pipelined",
    "Three requests in one segment are answered in order, each with its CSeq",
    ["R-RCTP-13", "R-RCTP-5"],
)
async def pipelined(ctx: Context) -> None:
    probe = await ctx.session()
    path = ctx.target.site_path
    await probe.send(b"".join(probe.request_bytes("CONNECT", path) for _ in range(3)))
    for _ in range(3):
        # Each answer's CSeq is its request's, in order (R-RCTP-5), as the probe matches them.
        ctx.expect_status(await probe.response(cseq_rule="R-RCTP-5"), 200)


@case(
    "rctp/msg/unknown-field",
    "A request with a header field the server does not know is answered as without it",
    ["R-RCTP-14"],
)
async def unknown_field(ctx: Context) -> None:
    probe = await ctx.control()
    answer = await probe.connect(ctx.target.site_path, [("X-Rcmlconf-Probe", "ignore me")])
    ctx.expect_status(answer, 200)


@case(
    "rctp/msg/bad-request-line",
    "A request line that does not parse is answered 400 and the connection closed",
    ["R-RCTP-8"],
)
async def bad_request_line(ctx: Context) -> None:
    probe = await ctx.control()
    await probe.send(b"CONNECT\r\nCSeq: 1\r\n\r\n")
    ctx.expect_status(await probe.response(), 400)
    closed = await probe.closes()
    ctx.expect(closed, "the connection closed", "it stayed open")


@case(
    "rctp/msg/header-section-unbounded",
    "A header line that passes 16384 bytes without ending is answered 431 without waiting for its"
    " end, and the connection closed",
    ["R-RCTP-16"],
)
async def header_section_unbounded(ctx: Context) -> None:
    # D-RCTP-9: a receiver stops reading at a limit. One that reads a head up to its empty line
    # and only then measures it buffers without bound and never answers; past the section's
    # limit the line has passed the header line's too, so either limit answers it.
    probe = await ctx.control()
    head = f"CONNECT {ctx.target.site_path} RCTP/2.0\r\nCSeq: 1\r\nX-Rcmlconf-Pad: ".encode()
    data = head + _filler(HEADER_SECTION + 1).encode()
    await _refused_and_closed(ctx, probe, data, 431, "R-RCTP-16")


@case(
    "rctp/msg/bad-header-line",
    "A header line without a colon, or whose name is not a token, is answered 400 and the"
    " connection closed",
    ["R-RCTP-8"],
)
async def bad_header_line(ctx: Context) -> None:
    # D-RCTP-10: a header that does not parse cannot be framed; skipping it as a field one does
    # not know (R-RCTP-14) would take the rest of the request for valid.
    lines = (b"User-Agent rcmlconf", b"User Agent: rcmlconf", b": rcmlconf", b"User(Agent): x")
    await _broken_connect(ctx, *(b" RCTP/2.0\r\nCSeq: 1\r\n%s\r\n\r\n" % line for line in lines))
