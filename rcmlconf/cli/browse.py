"""`rcmlconf browse PANEL.rxid`: the RCML browser, a panel in the user's web browser."""

from __future__ import annotations

import asyncio
import sys
import webbrowser
from pathlib import Path

import click

from rcmlconf.browse.bridge import Bridge
from rcmlconf.browse.links import robot_links
from rcmlconf.browse.panel import Panel, build_panel
from rcmlconf.browse.robot import BYE_WAIT
from rcmlconf.browse.security import Guard, is_loopback, new_token
from rcmlconf.browse.server import PanelServer
from rcmlconf.browse.sources import Invalid, Sources, Unreadable, load_sources
from rcmlconf.cli.client.inputs import check_rcml, check_url
from rcmlconf.cli.console import Output
from rcmlconf.cli.interrupts import Interrupts
from rcmlconf.cli.logs import log_lines
from rcmlconf.cli.params import seconds
from rcmlconf.cli.ready import write_ready
from rcmlconf.errors import ValueTextError
from rcmlconf.rcml.url import RctpUrl, http_base
from rcmlconf.reference.client.adapter import Client, RctpError
from rcmlconf.validate.report import summary_line
from rcmlconf.wording import plural


def _source(ctx: click.Context, param: click.Parameter, value: str) -> str:
    try:
        return check_rcml(value)
    except ValueTextError as exc:
        raise click.BadParameter(str(exc).replace("RCML", "RXID")) from None


def _connect(
    ctx: click.Context, param: click.Parameter, values: tuple[str, ...]
) -> dict[str, RctpUrl]:
    mapping = {}
    for value in values:
        href, sep, url = value.partition("=")
        if not sep or not href or not url:
            raise click.BadParameter(f"{value!r} is not HREF=rctp://HOST:PORT/PATH")
        try:
            mapping[href] = check_url(url)
        except ValueTextError as exc:
            raise click.BadParameter(str(exc)) from None
    return mapping


@click.command()
@click.argument("source", metavar="PANEL", callback=_source)
@click.option(
    "--host",
    default="127.0.0.1",
    show_default=True,
    help="The address the page is served on. Another than loopback lets other machines reach "
    "it; they still need the token in the printed URL.",
)
@click.option(
    "--port",
    type=click.IntRange(0, 65535),
    default=0,
    show_default=True,
    metavar="N",
    help="The page's port (0 picks a free one).",
)
@click.option("--open", "open_page", is_flag=True, help="Open the page in the default browser.")
@click.option(
    "--connect",
    "connect",
    multiple=True,
    metavar="HREF=URL",
    callback=_connect,
    help="Connect the session whose href is HREF to the RCTP server at URL, not to its RCML's "
    "site (a server started with --port 0, a robot behind a tunnel). Repeatable.",
)
@click.option(
    "--wait",
    is_flag=True,
    help="Start even when a robot's server is not there: the page says it is waiting, and "
    "connects once the server is up.",
)
@click.option(
    "--timeout",
    type=seconds(60.0),
    default=5.0,
    show_default=True,
    metavar="S",
    help="Seconds to fetch the panel and its RCML files (all together), and to wait for a"
    " connection or an answer.",
)
@click.option(
    "--ready-file",
    type=click.Path(dir_okay=False, path_type=Path),
    help='Once serving, write {"url": URL, "port": N} there (removed at exit): for scripts.',
)
@click.option("-v", "--verbose", count=True, help="Print a line per page, state and refusal.")
def browse(
    source: str,
    host: str,
    port: int,
    open_page: bool,
    connect: dict[str, RctpUrl],
    wait: bool,
    timeout: float,
    ready_file: Path | None,
    verbose: int,
) -> None:
    """Show the RXID panel PANEL (a file or an http(s) URL) in a web browser, linked to the
    robots its sessions name: the RCML browser of the paper's Fig. 5.

    The RXID and the RCML of each session (beside a local panel, or downloaded relative to
    its URL) are validated first, and each robot's server is reached (unless --wait). Then
    the page is served, at a URL with a random token: every request and the page's
    WebSocket need the token, a Host that is an address or localhost, and the page's own
    Origin. Each open page has its own RCTP sessions (two pages on one robot see each
    other's writes); reading widgets follow the robot by stream, data-change WRITEs or READ
    every 0.5 s, writing widgets send the user's input, and a refusal (busy, not acquired,
    forbidden) is shown in words next to its widget. docs/browse.md has the details.

    \b
    Exit status: 0 stopped by Ctrl-C or SIGTERM (every session said BYE);
      1 invalid RXID or RCML (diagnostics as `validate` prints them);
      2 usage error, an unreadable panel, a robot not there (without --wait), or the port
        in use.

    \b
    Examples:
      rcmlconf browse rcmlconf/reference/robots/camera/camera.rxid --open
      rcmlconf browse http://127.0.0.1:7331/camera.rxid
      rcmlconf browse panel.rxid --connect camera.rcml=rctp://127.0.0.1:7400/camera --wait
    """
    output = Output()
    sources = _load(output, source, timeout)
    unknown = sorted(connect.keys() - sources.robots.keys())
    if unknown:
        raise click.BadParameter(
            f"{unknown[0]!r} is no session href of {source} (they are: "
            f"{', '.join(sorted(sources.robots))})",
            param_hint="'--connect'",
        )
    base_url = source if source.lower().startswith(("http:", "https:")) else None
    panel = build_panel(sources.rxid, {h: r.model for h, r in sources.robots.items()}, base_url)
    urls = {href: connect.get(href, robot.model.site) for href, robot in sources.robots.items()}
    with log_lines(output, verbose, "rcmlconf.browse"):
        status = asyncio.run(
            _browse(output, panel, urls, host, port, timeout, wait, open_page, ready_file)
        )
    sys.exit(status)


def _load(output: Output, source: str, timeout: float) -> Sources:
    try:
        sources = load_sources(source, timeout)
    except Unreadable as exc:
        output.problem("browse", str(exc))
        sys.exit(2)
    except Invalid as exc:
        for diagnostic in exc.report.diagnostics:
            output.diagnostic(diagnostic)
        output.summary(summary_line([exc.report]), ok=False)
        sys.exit(1)
    for warning in sources.report.diagnostics:
        output.diagnostic(warning)
    return sources


async def _reachable(
    output: Output, urls: dict[str, RctpUrl], panel: Panel, timeout: float
) -> bool:
    """Every robot's server answers CONNECT (then BYE); else one line naming the first."""
    for href, url in urls.items():
        try:
            client = await Client.connect(url, panel.robots[href], timeout=timeout)
        except RctpError as exc:
            output.problem(
                "browse",
                f"the robot of session {href!r} is not there: {exc} ({url}); start its server,"
                " give its URL with --connect, or pass --wait",
            )
            return False
        await client.close(BYE_WAIT)
    return True


async def _browse(
    output: Output,
    panel: Panel,
    urls: dict[str, RctpUrl],
    host: str,
    port: int,
    timeout: float,
    wait: bool,
    open_page: bool,
    ready_file: Path | None,
) -> int:
    if not wait and not await _reachable(output, urls, panel, timeout):
        return 2
    links = robot_links(panel)
    guard = Guard(new_token(), port)
    server = PanelServer(guard, lambda name: Bridge(panel, links, urls, timeout, name))
    try:
        bound = await server.start(host, port)
    except OSError as exc:
        output.problem(
            "browse", f"cannot serve the page on {host} port {port}: {exc.strerror or exc}"
        )
        return 2
    shown_host = "127.0.0.1" if host in ("0.0.0.0", "::", "") else host
    url = f"{http_base(shown_host, bound)}/?token={guard.token}"
    output.err.line(
        [("browsing ", ""), (panel.title, "bold"), (f" ({plural(len(urls), 'robot')})", "")]
    )
    output.err.line([("  page  ", "dim"), (url, "cyan")])
    if not is_loopback(host):
        output.notice(
            f"serving on {host}: other machines can reach the page; only the token in the URL "
            "keeps them from driving the robot, so share it with no one"
        )
    output.err.line([("Ctrl-C to stop", "dim")])
    with Interrupts() as interrupts:
        try:
            if ready_file is not None and not write_ready(
                output, "browse", ready_file, {"url": url, "port": bound}
            ):
                await server.stop()
                return 2
            if open_page:
                webbrowser.open(url)
            await interrupts.wait()
            output.notice("stopping: BYE to every robot")
            await interrupts.race(server.stop(), count=2)
        finally:
            if ready_file is not None:
                ready_file.unlink(missing_ok=True)
    return 0
