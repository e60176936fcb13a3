"""rctp/msg: more of the message grammar — line endings, fields, framing, limits, targets, the
numbering and order of requests and answers (specs/rctp-2.0.md §2, D-RCTP-4 to D-RCTP-10, §2.1,
§2.2, R-RCTP-1 to R-RCTP-16)."""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import AsyncIterator

from rcmlconf.conformance.context import Context, expect_answer
from rcmlconf.conformance.picks import STRANGER, first, read_target, unknown_target, writable
from rcmlconf.conformance.probes.control import ControlProbe, Fields
from rcmlconf.conformance.registry import case
from rcmlconf.conformance.verdicts import Failed, Inconclusive
from rcmlconf.rcml.model import AccessType
from rcmlconf.rctp.fields import format_nodes, same_token
from rcmlconf.rctp.messages import TEXT_TYPE, VALUES_TYPE, VERSION, Message, Response
from rcmlconf.rctp.targets import format_target

#: D-RCTP-9.
START_LINE = 4096
HEADER_LINE = 4096
HEADER_SECTION = 16384
HEADER_FIELDS = 64
BODY = 4194304
#: A body that holds a whole request: a receiver that looks for messages inside bodies finds one.
INNER_REQUEST = b"FROBNICATE * RCTP/2.0\r\nCSeq: 99\r\n\r\n"


@case(
    "rctp/msg/bare-lf",
    "A request with a bare LF or CR as a line ending is answered 400 and the connection closed",
    ["R-RCTP-8"],
)
async def bare_lf(ctx: Context) -> None:
    await _broken_connect(
        ctx,
        b" RCTP/2.0\nCSeq: 1\n\n",
        b" RCTP/2.0\r\nCSeq: 1\nUser-Agent: rcmlconf\r\n\r\n",
        b" RCTP/2.0\r\nCSeq: 1\rUser-Agent: rcmlconf\r\n\r\n",
    )


@case(
    "rctp/msg/obs-fold",
    "A request with an obsolete folded header line is answered 400 and the connection closed",
    ["R-RCTP-8"],
)
async def obs_fold(ctx: Context) -> None:
    await _broken_connect(
        ctx, b" RCTP/2.0\r\nCSeq: 1\r\nUser-Agent: rcmlconf\r\n conformance\r\n\r\n"
    )


@case(
    "rctp/msg/space-before-colon",
    "A header field with white space before its colon is answered 400 and the connection closed",
    ["R-RCTP-8"],
)
async def space_before_colon(ctx: Context) -> None:
    await _broken_connect(ctx, b" RCTP/2.0\r\nCSeq: 1\r\nUser-Agent : rcmlconf\r\n\r\n")


@case(
    "rctp/msg/cseq-not-number",
    "A CSeq that is not a number from 1 to 2147483647 is answered 400 without CSeq, and the "
    "connection goes on",
    ["R-RCTP-11", "R-RCTP-3"],
)
async def cseq_not_number(ctx: Context) -> None:
    probe = await ctx.session()
    site = ctx.target.site_path
    for value in ("abc", "0", "-1", "+2", "2.0", "0x2", "2147483648", "12345678901", ""):
        fields = [("CSeq", value)]
        await probe.send(_request(probe, "CONNECT", site, fields, cseq=False))
        answer = await probe.response()
        expect_answer(ctx, answer, 400, f"CONNECT with CSeq {value!r}", "R-RCTP-11")
        echoed = answer.headers.get("CSeq")
        ctx.expect(
            echoed is None,
            f"no CSeq in the answer to CSeq {value!r} (D-RCTP-10: nothing to echo)",
            f"CSeq: {echoed}",
            "R-RCTP-3",
        )
    expect_answer(ctx, await probe.request("CONNECT", site), 200, "CONNECT afterwards")


@case(
    "rctp/msg/repeated-fields",
    "A request repeating CSeq, Session, Content-Type, Nodes or Transport is answered 400; a "
    "repeated field that may repeat is not",
    ["R-RCTP-11", "R-RCTP-14"],
)
async def repeated_fields(ctx: Context) -> None:
    probe = await ctx.session()
    assert probe.session is not None
    readable = read_target(ctx)
    once: list[tuple[str, str, tuple[str, str], bytes]] = [
        ("READ", readable, ("Session", probe.session), b""),
        ("WRITE", unknown_target(ctx), ("Content-Type", VALUES_TYPE), b"\0"),
    ]
    event = first(ctx, AccessType.EVENT)
    if event is not None and event.readable():
        nodes = ("Nodes", format_nodes([event.readable()[0].name]))
        once.append(("READ", format_target(event.path), nodes, b""))
    stream = first(ctx, AccessType.STREAM)
    if stream is not None:
        once.append(("SETUP", format_target(stream.path), ("Transport", "udp;client_port=9"), b""))
    cseq = probe.cseq + 1
    await probe.send(
        f"READ {readable} {VERSION}\r\nCSeq: {cseq}\r\nCSeq: {cseq}\r\n"
        f"Session: {probe.session}\r\n\r\n".encode()
    )
    expect_answer(ctx, await probe.response(), 400, "READ with CSeq twice")
    for method, target, field, body in once:
        await probe.send(_request(probe, method, target, [field, field], body))
        answer = await probe.response()
        expect_answer(ctx, answer, 400, f"{method} {target} with {field[0]} twice", "R-RCTP-11")
    repeated = [("X-Rcmlconf-Probe", "one"), ("X-Rcmlconf-Probe", "two")]
    answer = await probe.request("READ", readable, repeated)
    expect_answer(ctx, answer, 200, "READ with an unknown field twice", "R-RCTP-14")


@case(
    "rctp/msg/content-length-invalid",
    "A Content-Length that is not one decimal number is answered 400 and the connection closed",
    ["R-RCTP-8"],
)
async def content_length_invalid(ctx: Context) -> None:
    head = f"WRITE {unknown_target(ctx)} {VERSION}\r\nCSeq: 1\r\n".encode()
    values = ("abc", "-3", "+3", "0x3", "3 3", "3, 3", "3.0", "1e3", "")
    lengths = [[b"Content-Length: " + v.encode()] for v in values]
    lengths.append([b"Content-Length: 3", b"Content-Length: 4"])
    for fields in lengths:
        data = head + b"\r\n".join(fields) + b"\r\nContent-Type: application/rctp-values\r\n\r\nabc"
        await _refused_and_closed(ctx, await ctx.control(), data, 400)


@case(
    "rctp/msg/body-split-everywhere",
    "A request with a body, split in two at every byte, is framed by Content-Length alone: one "
    "answer each, none to the request-like body",
    ["R-RCTP-13", "R-RCTP-6"],
)
async def body_split_everywhere(ctx: Context) -> None:
    probe = await ctx.session()
    missing = unknown_target(ctx)
    cut = 0
    while True:
        cut += 1
        data = _request(probe, "WRITE", missing, (), INNER_REQUEST)
        if cut >= len(data):
            return
        await probe.send(data[:cut])
        await asyncio.sleep(0.002)
        await probe.send(data[cut:])
        # An answer to the request-like body has its CSeq, not the WRITE's (R-RCTP-6).
        answer = await probe.response(cseq_rule="R-RCTP-6")
        what = f"WRITE of a path that names no node, cut at byte {cut} of {len(data)}"
        expect_answer(ctx, answer, 404, what, "R-RCTP-13")


@case(
    "rctp/msg/write-without-content-length",
    "A WRITE without Content-Length, of a path the session holds, is answered 411 and the "
    "connection goes on",
    ["R-RCTP-6"],
    serial=True,
)
async def write_without_content_length(ctx: Context) -> None:
    probe = await ctx.session()
    named = writable(ctx)
    typed = [*named.fields(), ("Content-Type", "application/rctp-values")]
    async with holding(ctx, probe, named.path):
        await probe.send(_request(probe, "WRITE", named.target, typed))
        expect_answer(ctx, await probe.response(), 411, "WRITE without Content-Length")


@case(
    "rctp/msg/unsupported-content-type",
    "A WRITE whose body is not application/rctp-values is answered 415",
    ["R-RCTP-6"],
    serial=True,
)
async def unsupported_content_type(ctx: Context) -> None:
    probe = await ctx.session()
    named = writable(ctx)
    async with holding(ctx, probe, named.path):
        for media in ("text/plain; charset=utf-8", "application/octet-stream"):
            typed = [*named.fields(), ("Content-Type", media)]
            answer = await probe.request("WRITE", named.target, typed, b"\0\0\0\0")
            expect_answer(ctx, answer, 415, f"WRITE with Content-Type {media}")


@case(
    "rctp/msg/transfer-encoding",
    "A request with Transfer-Encoding is answered 400 and the connection closed",
    ["R-RCTP-8"],
)
async def transfer_encoding(ctx: Context) -> None:
    await _broken_connect(
        ctx, b" RCTP/2.0\r\nCSeq: 1\r\nTransfer-Encoding: chunked\r\n\r\n0\r\n\r\n"
    )


@case(
    "rctp/msg/start-line-limit",
    "A request line of 4096 bytes is answered (its CRLF not counted, D-RCTP-9); one of 4097 is "
    "answered 414 and the connection closed",
    ["R-RCTP-16", "R-RCTP-8"],
)
async def start_line_limit(ctx: Context) -> None:
    probe = await ctx.session()
    fixed = len(f"READ / {VERSION}")
    at = _request(probe, "READ", "/" + _filler(START_LINE - fixed))
    await probe.send(at)
    expect_answer(ctx, await probe.response(), 404, "READ with a 4096-byte request line")
    over = _request(probe, "READ", "/" + _filler(START_LINE + 1 - fixed))
    await _refused_and_closed(ctx, probe, over, 414, "R-RCTP-16")


@case(
    "rctp/msg/start-line-unbounded",
    "A request line that passes 4096 bytes without ending is answered 414 without waiting for "
    "its end, and the connection closed",
    ["R-RCTP-16"],
)
async def start_line_unbounded(ctx: Context) -> None:
    probe = await ctx.control()
    data = b"READ /" + _filler(2 * START_LINE).encode()
    await _refused_and_closed(ctx, probe, data, 414, "R-RCTP-16")


@case(
    "rctp/msg/header-line-limit",
    "A header line of 4096 bytes is accepted (its CRLF not counted, D-RCTP-9); one of 4097 is "
    "answered 431 and the connection closed",
    ["R-RCTP-16", "R-RCTP-8"],
)
async def header_line_limit(ctx: Context) -> None:
    probe = await ctx.session()
    site = ctx.target.site_path
    name = "X-Rcmlconf-Pad"
    fixed = len(f"{name}: ")
    at = _request(probe, "CONNECT", site, [(name, _filler(HEADER_LINE - fixed))])
    await probe.send(at)
    expect_answer(ctx, await probe.response(), 200, "CONNECT with a 4096-byte header line")
    over = _request(probe, "CONNECT", site, [(name, _filler(HEADER_LINE + 1 - fixed))])
    await _refused_and_closed(ctx, probe, over, 431, "R-RCTP-16")


@case(
    "rctp/msg/header-section-limit",
    "A header section under 16384 bytes and 64 fields is accepted; one above either limit is "
    "answered 431 and the connection closed",
    ["R-RCTP-16", "R-RCTP-8"],
)
async def header_section_limit(ctx: Context) -> None:
    site = ctx.target.site_path
    pads = [(f"X-Rcmlconf-Pad-{i}", _filler(3600)) for i in range(5)]
    probe = await ctx.session()
    await probe.send(_request(probe, "CONNECT", site, pads[:4]))
    expect_answer(ctx, await probe.response(), 200, "CONNECT with a 14.5 kB header section")
    await _refused_and_closed(ctx, probe, _request(probe, "CONNECT", site, pads), 431, "R-RCTP-16")
    # CSeq and Session, and the rest up to the limit: 64 fields, then 65.
    many = [(f"X-Rcmlconf-{i}", str(i)) for i in range(HEADER_FIELDS - 1)]
    probe = await ctx.session()
    await probe.send(_request(probe, "CONNECT", site, many[:-1]))
    expect_answer(ctx, await probe.response(), 200, "CONNECT with 64 header fields")
    await _refused_and_closed(ctx, probe, _request(probe, "CONNECT", site, many), 431, "R-RCTP-16")


@case(
    "rctp/msg/content-length-limit",
    "A body of 4194304 bytes is read whole; a Content-Length above it is answered 413, without "
    "the body, and the connection closed",
    ["R-RCTP-16", "R-RCTP-8"],
)
async def content_length_limit(ctx: Context) -> None:
    probe = await ctx.session()
    missing = unknown_target(ctx)
    await probe.send(_request(probe, "WRITE", missing, (), bytes(BODY)))
    answer = await probe.response()
    expect_answer(ctx, answer, 404, "WRITE of a path that names no node, 4194304-byte body")
    head = _request(probe, "WRITE", missing, (), b"\0")
    head = head.replace(b"Content-Length: 1\r\n", f"Content-Length: {BODY + 1}\r\n".encode())
    await _refused_and_closed(ctx, probe, head[:-1], 413, "R-RCTP-16")


@case(
    "rctp/msg/bad-targets",
    "Targets other than *, / or a percent-encoded path of XML Names are answered 400, and the "
    "connection goes on",
    ["R-RCTP-15"],
)
async def bad_targets(ctx: Context) -> None:
    probe = await ctx.session()
    readable = read_target(ctx)
    targets = (
        b"foo",
        b"**",
        b"rctp://robot.example/a",
        b"//",
        b"/a//b",
        b"/a/",
        b"/%zz",
        b"/%4",
        b"/%C3",
        b"/%2F",
        b"/%00",
        b"/a%20b",
        b"/1abc",
        b"/-a",
        b"/a;b",
        b"/a?b",
        b"/a#b",
        b"/a[b",
        b"/\xc3\xa9",
    )
    for target in targets:
        data = _request(probe, "READ", "/placeholder").replace(b"/placeholder", target, 1)
        await probe.send(data)
        # D-RCTP-25: the target is checked after framing; the connection goes on
        answer = await _answer(probe, "R-RCTP-15")
        expect_answer(ctx, answer, 400, f"READ {target.decode('latin-1')!r}")
    answer = await probe.request("READ", readable)
    expect_answer(ctx, answer, 200, f"READ {readable} afterwards")


@case(
    "rctp/msg/percent-encoded-target",
    "A target whose every character is percent-encoded, in upper or lower case hex, names the "
    "node it decodes to",
    ["R-RCTP-15"],
)
async def percent_encoded_target(ctx: Context) -> None:
    probe = await ctx.session()
    path = read_target(ctx, encoded=False)
    for hexes in ("%{:02X}", "%{:02x}"):
        encoded = "".join(
            "/" + "".join(hexes.format(byte) for byte in name.encode())
            for name in path[1:].split("/")
        )
        expect_answer(ctx, await probe.request("READ", encoded), 200, f"READ {encoded}")


@case(
    "rctp/msg/answers-echo-cseq",
    "Every answer, success or error, has the version RCTP/2.0 and the CSeq of its request",
    ["R-RCTP-3", "R-RCTP-2"],
)
async def answers_echo_cseq(ctx: Context) -> None:
    probe = await ctx.session()
    normal = read_target(ctx)
    requests: list[tuple[bytes, int]] = [
        (_request(probe, "READ", normal), 200),
        (_request(probe, "READ", unknown_target(ctx)), 404),
        (_request(probe, "FROBNICATE", "*"), 501),
        (_request(probe, "READ", normal, version="RCTP/2.1"), 505),
        (_request(probe, "READ", "/1abc"), 400),
        (_request(probe, "READ", "*"), 405),
        (_request(probe, "GO", unknown_target(ctx)), 455),
        (_request(probe, "READ", normal, [("Session", STRANGER)]), 454),
        (_request(probe, "CONNECT", ctx.target.site_path), 200),
    ]
    for data, status in requests:
        await probe.send(data)
        answer = await probe.response()  # with its request's CSeq, as the probe matches them
        expect_answer(ctx, answer, status, data.split(b"\r\n")[0].decode(), "R-RCTP-3")
        ctx.expect(answer.version == VERSION, VERSION, answer.version, "R-RCTP-2")


@case(
    "rctp/msg/answers-well-formed",
    "Answers with and without bodies end lines in CRLF, fold nothing, use no Transfer-Encoding, "
    "and type their bodies",
    ["R-RCTP-1", "R-RCTP-7", "R-RCTP-6"],
)
async def answers_well_formed(ctx: Context) -> None:
    probe = await ctx.session()
    readable = read_target(ctx)
    for method, target in (
        ("READ", readable),
        ("READ", unknown_target(ctx)),
        ("READ", "*"),
        ("FROBNICATE", "*"),
        ("CONNECT", ctx.target.site_path),
    ):
        # The probe reads answers with the strict parser: a bare LF or CR, a folded line, white
        # space before a colon or a passed limit fails the case (R-RCTP-1, R-RCTP-16).
        answer = await probe.request(method, target)
        what = f"the answer {answer.status} to {method} {target}"
        coding = answer.headers.get("Transfer-Encoding")
        ctx.expect(coding is None, f"{what} without Transfer-Encoding", coding or "", "R-RCTP-7")
        if not answer.body:
            continue
        # D-RCTP-8: values, or text for people in an error response
        media = VALUES_TYPE if answer.status == 200 else TEXT_TYPE
        given = answer.headers.get("Content-Type")
        expected = f"{what} with Content-Type: {media}"
        ctx.expect(same_token(given, media), expected, f"Content-Type: {given}", "R-RCTP-6")


@case(
    "rctp/msg/pipelined-mixed",
    "Thirty valid and invalid requests in one segment are answered in order, each with its CSeq "
    "and status",
    ["R-RCTP-5", "R-RCTP-13"],
)
async def pipelined_mixed(ctx: Context) -> None:
    probe = await ctx.session()
    normal = read_target(ctx)
    missing = unknown_target(ctx)
    site = ctx.target.site_path
    expected: list[tuple[str, int]] = []
    data = b""
    for _ in range(2):
        for request, status in (
            (_request(probe, "READ", normal), 200),
            (_request(probe, "FROBNICATE", "*"), 501),
            (_request(probe, "READ", missing), 404),
            (_request(probe, "READ", normal, version="RCTP/3.0"), 505),
            (_request(probe, "READ", normal, [("CSeq", "x")], cseq=False), 400),
            (_request(probe, "READ", "/1abc"), 400),
            (_request(probe, "READ", "*"), 405),
            (_request(probe, "GO", missing), 455),
            (_request(probe, "READ", normal, [("Session", STRANGER)]), 454),
            (_request(probe, "CONNECT", site), 200),
            (_request(probe, "CONNECT", site.rstrip("/") + "/rcmlconf-no-robot"), 404),
            (_request(probe, "SETUP", missing), 404),
            (_request(probe, "RELEASE", "*"), 200),
            (_request(probe, "READ", normal), 200),
        ):
            expected.append((request.split(b"\r\n")[0].decode(), status))
            data += request
    await probe.send(data)
    for index, (line, status) in enumerate(expected, start=1):
        # Each answer's CSeq is its request's, in order (R-RCTP-5), as the probe matches them.
        answer = await probe.response(cseq_rule="R-RCTP-5")
        what = f"answer {index} of {len(expected)}, to {line}"
        expect_answer(ctx, answer, status, what, "R-RCTP-5")


@case(
    "rctp/msg/lower-case-method",
    "A method name in another case than the table's is an unknown method: 501, and the "
    "connection goes on",
    ["R-RCTP-9"],
)
async def lower_case_method(ctx: Context) -> None:
    probe = await ctx.control()
    site = ctx.target.site_path
    for method in ("connect", "Connect"):
        await probe.send(_request(probe, method, site))
        expect_answer(ctx, await probe.response(), 501, f"{method} {site}")
    expect_answer(ctx, await probe.request("CONNECT", site), 200, f"CONNECT {site}")


@case(
    "rctp/msg/not-rctp-version",
    "A request line whose version is not RCTP/digits.digits does not parse: 400, and the "
    "connection closed",
    ["R-RCTP-8"],
)
async def not_rctp_version(ctx: Context) -> None:
    site = ctx.target.site_path
    for version in ("HTTP/1.1", "RCTP/2", "RCTP/2.0/"):
        probe = await ctx.control()
        await _refused_and_closed(
            ctx, probe, _request(probe, "CONNECT", site, version=version), 400
        )


@case(
    "rctp/msg/field-syntax-variants",
    "Field names in any case and white space (SP, HTAB) around values or none are accepted",
    ["R-RCTP-3", "R-RCTP-19"],
)
async def field_syntax_variants(ctx: Context) -> None:
    probe = await ctx.control()
    site = ctx.target.site_path
    normal = read_target(ctx)
    await probe.send(
        f"CONNECT {site} {VERSION}\r\ncseq:1\r\nuser-agent: \t rcmlconf \t\r\n\r\n".encode()
    )
    answer = await probe.response()
    expect_answer(ctx, answer, 200, "CONNECT with cseq:1", "R-RCTP-3")
    session = (answer.headers.get("Session") or "").split(";")[0].strip()
    await probe.send(
        f"READ {normal} {VERSION}\r\nCSEQ:\t2 \r\nsession:  {session}\t\r\n\r\n".encode()
    )
    answer = await probe.response()
    expect_answer(ctx, answer, 200, f"READ with session:  {session}", "R-RCTP-19")


# -- helpers -----------------------------------------------------------------------------------


def _request(
    probe: ControlProbe,
    method: str,
    target: str,
    fields: Fields = (),
    body: bytes = b"",
    *,
    cseq: bool = True,
    version: str = VERSION,
) -> bytes:
    """A request as `request_bytes` makes it (the next CSeq unless not `cseq`, the session unless
    `fields` name one), with any version."""
    data = probe.request_bytes(method, target, fields, body, cseq=None if cseq else 0)
    if not cseq:
        data = data.replace(b"CSeq: 0\r\n", b"", 1)
    if version != VERSION:
        data = data.replace(f" {VERSION}\r\n".encode(), f" {version}\r\n".encode(), 1)
    return data


def _filler(size: int) -> str:
    """`size` characters of an XML Name that names nothing."""
    return ("rcmlconf" + "x" * size)[:size]


@contextlib.asynccontextmanager
async def holding(ctx: Context, probe: ControlProbe, path: str) -> AsyncIterator[None]:
    """The privilege of `path` for the case's body, released after it (inconclusive if the
    privilege cannot be had: the rctp/priv cases check ACQUIRE)."""
    target = format_target(path)
    answer = await probe.request("ACQUIRE", target)
    if answer.status != 200:
        raise Inconclusive(f"ACQUIRE {path} was answered {answer.status} {answer.reason}")
    try:
        yield
    finally:
        with contextlib.suppress(Exception):
            await asyncio.wait_for(probe.request("RELEASE", target), ctx.wait)


async def _refused_and_closed(
    ctx: Context, probe: ControlProbe, data: bytes, status: int, requirement: str = "R-RCTP-8"
) -> None:
    """`data` cannot be framed: answered `status`, then the connection closed (D-RCTP-10)."""
    await probe.send(data)
    answer = await _answer(probe, requirement)
    what = data.split(b"\r\n")[0][:60].decode("latin-1")
    expect_answer(ctx, answer, status, f"the answer to {what!r}", requirement)
    closed = await probe.closes()
    ctx.expect(closed, "the connection closed after the answer", "it stayed open", requirement)


async def _broken_connect(ctx: Context, *rests: bytes) -> None:
    """CONNECT of the site path and each of `rests`, which breaks the grammar, on a connection of
    its own: answered 400, then the connection closed."""
    site = ctx.target.site_path.encode()
    for rest in rests:
        await _refused_and_closed(ctx, await ctx.control(), b"CONNECT " + site + rest, 400)


async def _answer(probe: ControlProbe, requirement: str) -> Response:
    """The next response; none (a closed connection, silence) fails `requirement`."""
    try:
        return await probe.response()
    except Failed as failed:
        if failed.requirement != "R-RCTP-5":
            raise
        raise Failed(requirement, "an answer", failed.actual) from None


def expect_cseq(
    ctx: Context, message: Message, cseq: int, requirement: str | None = "R-RCTP-3"
) -> None:
    given = message.headers.get("CSeq")
    ctx.expect(given == str(cseq), f"CSeq: {cseq}", f"CSeq: {given}", requirement)
