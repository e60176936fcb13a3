"""rctp/client, the message grammar from the other side: the malformed requests the server cases
send a server, sent by the played server to the client under test once its session is open
(specs/rctp-2.0.md D-RCTP-4 to D-RCTP-10, R-RCTP-8, R-RCTP-9, R-RCTP-11). A request that cannot
be framed is answered with its status and the connection closed; one that is framed but wrong is
answered and the connection goes on."""

from __future__ import annotations

from rcmlconf.conformance.cases.rctp_client.answers import answer_to, client_case
from rcmlconf.conformance.context import Context
from rcmlconf.conformance.probes.control import ControlProbe
from rcmlconf.rctp.reader import LIMITS

#: Requests that cannot be framed (D-RCTP-10), by case: what is wrong, the request ({s} the
#: session), the status that answers it, and the requirement that status is judged by (R-RCTP-8;
#: R-RCTP-16 for a limit the server cases judge so too).
_UNFRAMEABLE: dict[str, tuple[str, bytes, int, str]] = {
    "request-bare-lf": (
        "lines ending in a bare LF",
        b"BYE * RCTP/2.0\nCSeq: 1\nSession: {s}\n\n",
        400,
        "R-RCTP-8",
    ),
    "request-obs-fold": (
        "a folded header line",
        b"BYE * RCTP/2.0\r\nCSeq: 1\r\nSession: {s}\r\nReason: shutdown\r\n  now\r\n\r\n",
        400,
        "R-RCTP-8",
    ),
    "request-space-before-colon": (
        "white space before a field's colon",
        b"BYE * RCTP/2.0\r\nCSeq: 1\r\nSession: {s}\r\nReason : shutdown\r\n\r\n",
        400,
        "R-RCTP-8",
    ),
    "request-not-rctp-version": (
        "another protocol's version, HTTP/1.1",
        b"BYE * HTTP/1.1\r\nCSeq: 1\r\nSession: {s}\r\n\r\n",
        400,
        "R-RCTP-8",
    ),
    "request-content-length-invalid": (
        "a Content-Length that is not a number",
        b"WRITE /settings RCTP/2.0\r\nCSeq: 1\r\nSession: {s}\r\nContent-Length: 1x\r\n\r\n",
        400,
        "R-RCTP-8",
    ),
    "request-transfer-encoding": (
        "Transfer-Encoding, which RCTP/2.0 does not use",
        b"WRITE /settings RCTP/2.0\r\nCSeq: 1\r\nSession: {s}\r\nTransfer-Encoding: chunked"
        b"\r\n\r\n0\r\n\r\n",
        400,
        "R-RCTP-8",
    ),
    "request-start-line-limit": (
        f"a request line past {LIMITS.start_line} bytes",
        b"STOP /" + b"a" * LIMITS.start_line + b" RCTP/2.0\r\nCSeq: 1\r\nSession: {s}\r\n\r\n",
        414,
        "R-RCTP-8",
    ),
    "header-line-too-long": (
        f"a header line past {LIMITS.header_line} bytes",
        # A BYE is what a client without the limit would answer 200.
        b"BYE * RCTP/2.0\r\nCSeq: 1\r\nSession: {s}\r\nX-Rcmlconf-Long: "
        + b"x" * (LIMITS.header_line + 1000)
        + b"\r\n\r\n",
        431,
        "R-RCTP-16",
    ),
    "request-header-section-limit": (
        f"a header section past {LIMITS.header_section} bytes, each line within its limit",
        b"BYE * RCTP/2.0\r\nCSeq: 1\r\nSession: {s}\r\n"
        + b"".join(b"X-Rcmlconf-%d: %s\r\n" % (i, b"x" * 3600) for i in range(5))
        + b"\r\n",
        431,
        "R-RCTP-16",
    ),
    "request-header-fields-limit": (
        f"more than {LIMITS.header_fields} header fields",
        b"BYE * RCTP/2.0\r\nCSeq: 1\r\nSession: {s}\r\n"
        + b"".join(b"X-Rcmlconf-%d: %d\r\n" % (i, i) for i in range(LIMITS.header_fields))
        + b"\r\n",
        431,
        "R-RCTP-8",
    ),
    "request-content-length-limit": (
        f"a Content-Length above {LIMITS.body} bytes",
        b"WRITE /settings RCTP/2.0\r\nCSeq: 1\r\nSession: {s}\r\nContent-Length: "
        + str(LIMITS.body + 1).encode()
        + b"\r\nContent-Type: application/rctp-values\r\n\r\n",
        413,
        "R-RCTP-8",
    ),
}


def _unframeable(name: str, what: str, request: bytes, status: int, requirement: str) -> None:
    @client_case(
        f"rctp/client/{name}",
        f"The client answers a server request with {what} with {status} and closes the connection",
        list(dict.fromkeys([requirement, "R-RCTP-8"])),
    )
    async def refused(ctx: Context) -> None:
        probe, _ = await ctx.client_session()
        answer = await answer_to(ctx, probe, request.replace(b"{s}", str(probe.session).encode()))
        ctx.expect_status(answer, status, requirement)
        closed = await probe.closes()
        ctx.expect(closed, "the connection closed (D-RCTP-10)", "it stayed open", "R-RCTP-8")


for _name, (_what, _request, _status, _requirement) in _UNFRAMEABLE.items():
    _unframeable(_name, _what, _request, _status, _requirement)


#: Requests that are framed but wrong, by case: what is wrong, the request, its status, and the
#: requirement (D-RCTP-10: answered, and the connection goes on).
_WRONG: dict[str, tuple[str, bytes, int, str]] = {
    "cseq-not-number": (
        "a CSeq that is not a number",
        b"BYE * RCTP/2.0\r\nCSeq: abc\r\nSession: {s}\r\n\r\n",
        400,
        "R-RCTP-11",
    ),
    "cseq-twice": (
        "CSeq twice",
        b"BYE * RCTP/2.0\r\nCSeq: 1\r\nCSeq: 1\r\nSession: {s}\r\n\r\n",
        400,
        "R-RCTP-11",
    ),
    "cseq-out-of-range": (
        "a CSeq above 2147483647, the largest",
        b"BYE * RCTP/2.0\r\nCSeq: 2147483648\r\nSession: {s}\r\n\r\n",
        400,
        "R-RCTP-11",
    ),
    "session-twice": (
        "Session twice, a field that may appear once",
        b"BYE * RCTP/2.0\r\nCSeq: 1\r\nSession: {s}\r\nSession: {s}\r\n\r\n",
        400,
        "R-RCTP-11",
    ),
    "lower-case-method": (
        "the method in lower case, an unknown method",
        b"bye * RCTP/2.0\r\nCSeq: 1\r\nSession: {s}\r\n\r\n",
        501,
        "R-RCTP-9",
    ),
}


def _wrong(name: str, what: str, request: bytes, status: int, requirement: str) -> None:
    @client_case(
        f"rctp/client/{name}",
        f"The client answers a server request with {what} with {status}, and answers the next"
        " request on the same connection",
        [requirement],
    )
    async def answered(ctx: Context) -> None:
        probe, _ = await ctx.client_session()
        answer = await answer_to(ctx, probe, request.replace(b"{s}", str(probe.session).encode()))
        ctx.expect_status(answer, status, requirement)
        # The request's CSeq was read only if it was one number (the numbering goes on from it,
        # D-RCTP-6); any answer to the next request shows the connection went on.
        probe.cseq = int(answer.headers.get("CSeq") or 0)
        await answer_to(ctx, probe, probe.request_bytes("BYE", "*", [("Reason", "shutdown")]))


for _name, (_what, _request, _status, _requirement) in _WRONG.items():
    _wrong(_name, _what, _request, _status, _requirement)


#: How far under its limit request-at-limits keeps its header section: D-RCTP-9 counts the CRLFs
#: between the section's lines, and a reader that counts the last line's too (the foreign
#: client does) is off by that much only, a slip no peer feels; a limit a line short is not.
SECTION_SHORT = 2


@client_case(
    "rctp/client/request-at-limits",
    f"Requests at D-RCTP-9's limits are no requests past them: a STOP whose request line is"
    f" {LIMITS.start_line} bytes is answered 455 (no access set up), a BYE of"
    f" {LIMITS.header_fields} fields, one line of {LIMITS.header_line} bytes and a header section"
    f" of {LIMITS.header_section - SECTION_SHORT} is answered 200",
    ["R-RCTP-68", "R-RCTP-23"],
)
async def request_at_limits(ctx: Context) -> None:
    probe, _ = await ctx.client_session()
    # A path of names of 99 bytes (a name is at most 255, D-RCML-3) as long as the line allows.
    room = LIMITS.start_line - len("STOP  RCTP/2.0")
    target = ("/" + "a" * 99) * (room // 100) + "/" + "a" * (room % 100 - 1)
    answer = await answer_to(ctx, probe, probe.request_bytes("STOP", target))
    ctx.expect_status(  # an off-by-one limit answers 414
        answer, 455, "R-RCTP-68", what=f"STOP with a request line of {LIMITS.start_line} bytes"
    )
    answer = await answer_to(ctx, probe, _at_header_limits(probe))
    ctx.expect_status(  # an off-by-one limit answers 431
        answer,
        200,
        "R-RCTP-23",
        what=f"BYE with {LIMITS.header_fields} fields, a line of {LIMITS.header_line} bytes and"
        f" a section of {LIMITS.header_section - SECTION_SHORT}",
    )


def _at_header_limits(probe: ControlProbe) -> bytes:
    """A BYE at the header limits of D-RCTP-9: as many fields as allowed, the first filler line
    as long as a line may be, and the section (its lines and the CRLFs between them) as long as
    a section may be, less `SECTION_SHORT`."""
    cseq = probe.cseq + 1
    names = [f"X-Rcmlconf-{i:02d}" for i in range(LIMITS.header_fields - 2)]  # CSeq, Session
    sizes = dict.fromkeys(names, 1)
    full = LIMITS.header_section - SECTION_SHORT

    def section() -> int:
        data = probe.request_bytes("BYE", "*", [(n, "x" * sizes[n]) for n in names], cseq=cseq)
        return len(data.split(b"\r\n", 1)[1].split(b"\r\n\r\n", 1)[0])

    for name in names:  # each filler line grows to the line limit until the section is full
        line = len(f"{name}: ")
        sizes[name] += min(LIMITS.header_line - line - sizes[name], full - section())
    probe.cseq = cseq
    return probe.request_bytes("BYE", "*", [(n, "x" * sizes[n]) for n in names], cseq=cseq)
