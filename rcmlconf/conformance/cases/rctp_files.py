"""rctp/files: the robot's files over HTTP/1.1 on the TCP port after RCTP's, for a target whose
ICS declares `files` (specs/rctp-2.0.md D-RCTP-29, R-RCTP-62 to R-RCTP-65): the index at `/`,
the RCML file and the RXID files its `UserInterface` links name, HEAD, and a persistent
connection.

The robot under test is known (`--rcml`, or the RCML its files list): the RCML a case fetches
must describe it (the same site path and node paths), and the RXID files a case expects are those
the fetched RCML's relative `UserInterface` links name, resolved against the RCML file's URL.
Each request but those of rctp/files/persistent goes on a connection of its own that says
`Connection: close`, so that how a server keeps connections fails that case alone.
"""

from __future__ import annotations

import posixpath
from dataclasses import dataclass
from html.parser import HTMLParser
from urllib.parse import quote, unquote, urljoin, urlsplit

from rcmlconf.conformance.context import Context
from rcmlconf.conformance.probes.files import Answer, FilesProbe
from rcmlconf.conformance.registry import case
from rcmlconf.conformance.verdicts import Failed, Inconclusive, NotApplicable
from rcmlconf.rcml.model import RcmlDocument
from rcmlconf.rcml.url import FILES_PORT_OFFSET
from rcmlconf.validate.validator import Validator
from rcmlconf.wording import shorten

INDEX, FILE, HEAD, PERSISTENT = "R-RCTP-62", "R-RCTP-63", "R-RCTP-64", "R-RCTP-65"
#: The case that checks what each of these requirements asks, for an inconclusive's reason.
_CHECKED_BY = {INDEX: "rctp/files/index", FILE: "rctp/files/get"}
#: The `.rcml` links of an index a case tries, at most, for the robot's RCML.
MOST_RCML_LINKS = 8
#: The links a failure lists, at most.
_SHOWN_LINKS = 12
#: A few requests, each answer read whole: more than a case's default 5 s.
TIMEOUT = 10.0
#: How long a HEAD's body, sent with its head, is waited for (seconds, --timeout-scale applies).
BODY_WAIT = 0.5
#: rctp/files/persistent's requests of `/`, in turn: POST, which D-RCTP-29 serves nothing by (its
#: answer's status is not judged, its framing is), and a last GET that says `Connection: close`.
IN_TURN = ("GET", "HEAD", "POST", "GET")
#: Characters a request target keeps unencoded besides `/`: RFC 3986's sub-delims, `:` and `@`.
_PATH_SAFE = "/:@!$&'()*+,;="
_NO_RXID = "the robot's RCML links no RXID file by a relative reference"


@dataclass(frozen=True, slots=True)
class Files:
    """What the server lists and serves of the robot under test, as request targets."""

    #: The paths the index links to, percent-decoded, in the page's order.
    listed: tuple[str, ...]
    #: The robot's RCML file.
    rcml: str
    #: The RXID files its relative `UserInterface` links name (D-RCTP-29).
    rxids: tuple[str, ...]

    @property
    def targets(self) -> tuple[str, ...]:
        return ("/", self.rcml, *self.rxids)


async def fetch(ctx: Context, method: str, target: str, requirement: str) -> Answer:
    """One request on a connection of its own, which the request asks the server to close."""
    probe = await connect(ctx, requirement)
    return await probe.ask(method, target, requirement, last=True)


async def connect(ctx: Context, requirement: str) -> FilesProbe:
    """A connection to the files: on the TCP port after the RCTP server's (D-RCTP-29)."""
    if ctx.target.server is None:
        raise NotApplicable("no RCTP server under test (--target)")
    host, port = ctx.target.server
    probe = await FilesProbe.open(
        (host, port + FILES_PORT_OFFSET), ctx.transcript, ctx.wait, requirement
    )
    ctx.on_close(probe.close)
    return probe


async def find_files(ctx: Context, judged: str | None = None) -> Files:
    """The index at `/` and the robot's RCML it links to. A wrong answer fails the case when
    `judged` names the requirement it breaks (INDEX or FILE); otherwise the case cannot go on,
    and is inconclusive: the case of that requirement checks it. No answer at all fails any case
    under the requirement of the request, as a control connection's missing answer does."""

    def fault(requirement: str, expected: str, actual: str) -> Failed | Inconclusive:
        if requirement == judged:
            return Failed(requirement, expected, actual)
        checker = _CHECKED_BY[requirement]
        return Inconclusive(f"expected {expected}; got {actual} ({checker} checks it)")

    index = await fetch(ctx, "GET", "/", INDEX)
    if index.status != 200:
        raise fault(INDEX, "GET /: 200", index.status_line)
    if index.media_type != "text/html":
        raise fault(
            INDEX, "GET /: an HTML page (text/html)", f"Content-Type {index.media_type or '-'}"
        )
    listed = _listed(index.body)
    rcmls = [path for path in listed if path.endswith(".rcml")][:MOST_RCML_LINKS]
    if not rcmls:
        raise fault(
            INDEX, "GET /: a link to the RCML file (a path ending in .rcml)", _links(listed)
        )
    wrong: list[str] = []
    for path in rcmls:
        target = _target(path)
        answer = await fetch(ctx, "GET", target, FILE)
        model, why = _as_robot(ctx.robot, answer, target)
        if model is not None:
            return Files(tuple(listed), target, _rxids(model, path))
        wrong.append(why)
    # One RCML linked: its GET is wrong; several, none the robot's: the index links others.
    broken = FILE if len(rcmls) == 1 else INDEX
    raise fault(
        broken, "GET of the linked RCML file: 200 and the robot under test's", "; ".join(wrong)
    )


# -- the cases ---------------------------------------------------------------------------------


@case(
    "rctp/files/index",
    "GET / on the port after RCTP's is answered 200 with an HTML page linking the RCML file and "
    "each RXID file its UserInterface links name",
    [INDEX],
    timeout=TIMEOUT,
    features=["files"],
)
async def index(ctx: Context) -> None:
    files = await find_files(ctx, INDEX)
    if not files.rxids:
        ctx.cannot_check(f"the RXID files listed: {_NO_RXID}")
    unlisted = [target for target in files.rxids if unquote(target) not in files.listed]
    ctx.expect(
        not unlisted,
        f"GET /: links to {', '.join(files.rxids)} (the RCML's UserInterface links)",
        f"none to {', '.join(unlisted)}; {_links(files.listed)}",
    )


@case(
    "rctp/files/get",
    "GET of the RCML file the index links is answered 200 with the robot's RCML, and GET of each "
    "RXID file its UserInterface links name, at its name relative to the RCML, with that RXID",
    [FILE],
    timeout=TIMEOUT,
    features=["files"],
)
async def get(ctx: Context) -> None:
    files = await find_files(ctx, FILE)  # the RCML's own GET is judged there
    if not files.rxids:
        ctx.cannot_check(f"the RXID files' GET: {_NO_RXID}")
    for target in files.rxids:
        answer = await fetch(ctx, "GET", target, FILE)
        ctx.expect(answer.status == 200, f"GET {target}: 200", answer.status_line)
        kind = Validator().load_bytes(answer.body, target, suffix=".rxid")[0].kind
        ctx.expect(
            kind == "rxid",
            f"GET {target}: the RXID document the RCML links (root <rxid>)",
            f"{f'a document of root <{kind}>' if kind else 'no document'}:"
            f" {shorten(repr(answer.body[:80]))}",
        )


@case(
    "rctp/files/head",
    "HEAD of /, of the RCML file and of each RXID file is answered with the status and "
    "Content-Length of a GET of it, and no body",
    [HEAD],
    timeout=TIMEOUT,
    features=["files"],
)
async def head(ctx: Context) -> None:
    files = await find_files(ctx)
    for target in files.targets:
        got = await fetch(ctx, "GET", target, INDEX if target == "/" else FILE)
        probe = await connect(ctx, HEAD)
        answer = await probe.ask("HEAD", target, HEAD, last=True)
        ctx.expect(
            (answer.status, answer.header("content-length"))
            == (got.status, got.header("content-length")),
            f"HEAD {target}: as GET, {got.status} with Content-Length"
            f" {got.header('content-length') or '-'}",
            f"{answer.status} with Content-Length {answer.header('content-length') or '-'}",
        )
        # h11 reads no body after a HEAD answer: what follows it is one. It comes with the head,
        # so a server that keeps the connection open after it is not waited for longer.
        extra, _ = await probe.closed(BODY_WAIT * ctx.scale)
        ctx.expect(
            not extra,
            f"HEAD {target}: no body (RFC 9110 §9.3.2)",
            f"{len(extra)} bytes after the head: {shorten(repr(extra[:80]))}",
        )


@case(
    "rctp/files/persistent",
    "GET /, HEAD /, POST / and GET / saying Connection: close, on one HTTP/1.1 connection, are"
    " each answered whole, and the connection closes after an answer that says Connection: close",
    [PERSISTENT, HEAD],
    timeout=TIMEOUT,
    features=["files"],
)
async def persistent(ctx: Context) -> None:
    probe = await connect(ctx, PERSISTENT)
    for number, method in enumerate(IN_TURN, 1):
        last = number == len(IN_TURN)
        kept = probe.reusable and number > 1
        if not probe.reusable:  # the last answer said Connection: close, and it closed
            probe = await connect(ctx, PERSISTENT)
        try:
            answer = await probe.ask(method, "/", PERSISTENT, last=last)
        except Failed as failed:
            if not kept:
                raise
            raise Failed(
                PERSISTENT,
                f"{method} / answered whole: request {number} of a connection whose answers kept"
                " it (no Connection: close, RFC 9112 §9.3)",
                failed.actual,
            ) from None
        if method == "HEAD" and probe.unread:  # h11 read no body: these bytes are one
            raise Failed(
                HEAD,
                "HEAD /: no body (RFC 9110 §9.3.2)",
                f"{shorten(repr(probe.unread[:80]))} after the head",
            )
        if not answer.closing:
            ctx.transcript.note(
                f"{probe.name}: answer {number} keeps the connection (RFC 9112 §9.3)"
            )
            continue
        extra, closed = await probe.closed(ctx.wait)
        said = "asked with" if last else "answered with"
        ctx.expect(
            closed and not extra,
            f"{method} / {said} Connection: close: the connection closed after its answer"
            " (RFC 9112 §9.6)",
            f"{len(extra)} more bytes" if extra else f"still open {ctx.wait:g} s later",
        )


# -- reading the index and the files -----------------------------------------------------------


class _Index(HTMLParser):
    """The paths an index page's `<a href>` links name, resolved against `/` and
    percent-decoded, each once, in the page's order."""

    def __init__(self) -> None:
        super().__init__()
        self.paths: list[str] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        for name, value in attrs if tag == "a" else ():
            if name == "href" and value:
                self._add(value)

    def _add(self, href: str) -> None:
        try:
            path = unquote(urlsplit(urljoin("http://files/", href)).path)
        except ValueError:  # `http://[::1`: the page is the target's, not to be trusted
            return
        if path not in self.paths:
            self.paths.append(path)


def _listed(page: bytes) -> list[str]:
    index = _Index()
    index.feed(page.decode("utf-8", "replace"))
    return index.paths


def _links(listed: list[str] | tuple[str, ...]) -> str:
    shown = ", ".join(listed[:_SHOWN_LINKS]) + (" ..." if len(listed) > _SHOWN_LINKS else "")
    return f"links to {shown}" if listed else "no link"


def _target(path: str) -> str:
    """A decoded path as a request target."""
    return quote(path, safe=_PATH_SAFE)


def _as_robot(robot: RcmlDocument, answer: Answer, target: str) -> tuple[RcmlDocument | None, str]:
    """The RCML model of a GET's answer when it is the robot under test's; else why not."""
    if answer.status != 200:
        return None, f"GET {target}: {answer.status_line}"
    report, model = Validator().load_bytes(answer.body, target, suffix=".rcml")
    if not isinstance(model, RcmlDocument):
        first = report.diagnostics[0].to_text() if report.diagnostics else "not RCML"
        return None, f"GET {target}: no valid RCML ({first})"
    if model.site.path != robot.site.path or list(model.nodes) != list(robot.nodes):
        return None, (
            f"GET {target}: the RCML of another robot (site path {model.site.path},"
            f" {len(model.nodes)} nodes; the robot under test's: {robot.site.path},"
            f" {len(robot.nodes)} nodes)"
        )
    return model, ""


def _rxids(model: RcmlDocument, rcml_path: str) -> tuple[str, ...]:
    """The request targets of the RXID files the RCML's `UserInterface` links name by a
    relative reference that stays in the RCML file's directory (D-RCTP-29)."""
    directory = rcml_path.rsplit("/", 1)[0] + "/"
    found: list[str] = []
    for link in model.links:
        parts = urlsplit(link.href)
        if link.kind != "UserInterface" or parts.scheme or parts.netloc:
            continue
        relative = posixpath.normpath(unquote(parts.path)) if parts.path else ""
        if relative in ("", ".", "..") or relative.startswith(("/", "../")):  # not a file in it
            continue
        path = directory + relative
        if _target(path) not in found:
            found.append(_target(path))
    return tuple(found)
