"""`rcmlconf serve ROBOT.rcml`: the reference server, until Ctrl-C."""

from __future__ import annotations

import asyncio
import errno
import os
import socket
import sys
from collections.abc import Callable
from pathlib import Path

import click

from rcmlconf.cli.console import Output
from rcmlconf.cli.interrupts import Interrupts
from rcmlconf.cli.logs import log_lines
from rcmlconf.cli.models import load_or_exit
from rcmlconf.cli.ready import write_ready
from rcmlconf.cli.serve_limits import limit_options, limits_from
from rcmlconf.rcml.url import DEFAULT_PORT, FILES_PORT_OFFSET, http_base
from rcmlconf.rctp.fields import DEFAULT_SESSION_TIMEOUT
from rcmlconf.reference.drivers import AUTO, DRIVERS, DriverError, choose_driver
from rcmlconf.reference.faults import faults_named, names
from rcmlconf.reference.server.adapter import ReferenceServer, ServerSettings
from rcmlconf.reference.server.collector import settle
from rcmlconf.validate.validator import load_robot
from rcmlconf.wording import plural

_PORT = click.IntRange(0, 65535)
#: Free pairs of ports `--port 0` tries, at most: another process may take one before the
#: server binds it.
_PAIR_TRIES = 5


@click.command()
@click.argument("rcml", metavar="ROBOT.rcml", type=click.Path(path_type=Path))
@click.option("--host", default="127.0.0.1", show_default=True, help="The address to listen on.")
@click.option(
    "--port",
    type=_PORT,
    metavar="N",
    help=f"RCTP's TCP port and the data stream's UDP port. Default: the port of the RCML's "
    f"site URL, else {DEFAULT_PORT}. 0 picks free ones.",
)
@click.option(
    "--http-port",
    type=_PORT,
    metavar="N",
    help="The HTTP port of the robot's files. Default: --port + 1 (with --port 0, the port"
    " after the one picked). 0 picks a free one.",
)
@click.option("--no-http", is_flag=True, help="Serve no files over HTTP.")
@click.option(
    "--driver",
    type=click.Choice([AUTO, *DRIVERS]),
    default=AUTO,
    show_default=True,
    help="What moves the robot: auto picks the simulation made for the RCML, else sim.",
)
@click.option("--seed", type=int, default=0, show_default=True, help="The simulation's seed.")
@click.option(
    "--session-timeout",
    type=click.IntRange(1, 99999),
    default=DEFAULT_SESSION_TIMEOUT,
    show_default=True,
    metavar="S",
    help="Seconds of silence after which a session is ended (D-RCTP-11).",
)
@click.option(
    "--ready-file",
    type=click.Path(dir_okay=False, path_type=Path),
    help='Once listening, write {"rctp": URL, "data_port": N, "http": URL or null} there '
    "(removed at exit): for scripts that start the server with --port 0.",
)
@click.option(
    "--fault",
    "faults",
    type=click.Choice(names("server")),
    multiple=True,
    metavar="NAME",
    help="Misbehave as NAME says (repeat for several): for testing a conformance harness, never "
    "for a real robot. NAME is one of " + ", ".join(names("server")) + ".",
)
@limit_options
@click.option(
    "-v",
    "--verbose",
    count=True,
    help="Print a line per request on stdout (-vv: the data stream's events too).",
)
def serve(
    rcml: Path,
    host: str,
    port: int | None,
    http_port: int | None,
    no_http: bool,
    driver: str,
    seed: int,
    session_timeout: int,
    ready_file: Path | None,
    faults: tuple[str, ...],
    max_connections: int,
    max_connections_per_peer: int,
    max_sessions_per_peer: int,
    slow_timeout: float,
    verbose: int,
) -> None:
    """Serve the robot ROBOT.rcml describes: RCTP/2.0 on TCP, its data stream on UDP, and its
    RCML and RXID files on HTTP (paper Fig. 5), until Ctrl-C or SIGTERM.

    The RCML is validated first; an invalid one is reported as `validate` reports it. A driver
    simulates the robot (camera and rover for the bundled robots, sim for any other). At the
    end every session gets BYE with `Reason: shutdown`.

    One client cannot hold the others up (D-RCTP-32): connections and sessions are capped, in
    all and per address, a connection too slow to CONNECT or to finish a request is closed, and
    a burst of pipelined requests is answered a slice at a time.

    \b
    Exit status: 0 stopped by Ctrl-C or SIGTERM; 1 invalid RCML;
      2 usage error, unreadable RCML, or a port in use.

    \b
    Examples:
      rcmlconf serve rcmlconf/reference/robots/camera/camera.rcml
      rcmlconf serve -v --port 7400 robot.rcml
      rcmlconf serve --port 0 --http-port 0 --ready-file ready.json robot.rcml
    """
    output = Output()
    if no_http and http_port is not None:
        raise click.UsageError("--http-port and --no-http exclude each other")
    model = load_or_exit(output, "serve", rcml, load_robot)
    try:
        chosen = choose_driver(driver, model)
    except DriverError as exc:
        raise click.UsageError(str(exc)) from None
    tcp = model.site.port_or_default if port is None else port
    limits = limits_from(
        max_connections, max_connections_per_peer, max_sessions_per_peer, slow_timeout
    )
    for below in limits.below_floor():
        output.notice(f"{below}: below R-RCTP-67's floor, clients may be refused or cut off")
    paired = tcp == 0 and http_port is None and not no_http

    def server() -> ReferenceServer:
        rctp, files = (_free_pair(host), None) if paired else (tcp, http_port)
        settings = ServerSettings(
            host=host,
            port=rctp,
            http_port=None if no_http else _http_port(rctp, files),
            seed=seed,
            session_timeout=session_timeout,
            faults=faults_named(faults),
            limits=limits,
        )
        return ReferenceServer(rcml, model, chosen, settings)

    with log_lines(output, verbose, "rcmlconf.server"):
        status = asyncio.run(_serve(server, _PAIR_TRIES if paired else 1, output, ready_file))
    sys.exit(status)


def _http_port(tcp: int, http_port: int | None) -> int:
    """--http-port, else the port after RCTP's (where `rcmlconf client` looks), else any."""
    if http_port is not None:
        return http_port
    return tcp + FILES_PORT_OFFSET if tcp > 0 and tcp + FILES_PORT_OFFSET <= 65535 else 0


def _free_pair(host: str) -> int:
    """For --port 0: a port P of `host` free for RCTP (TCP and UDP) with P + 1 free for the
    files, where a client given only the RCTP URL looks (D-RCTP-29); 0 (any port, the files
    on any other) when none is found, or `host` does not resolve (the server says so)."""
    try:
        family, _, _, _, address = socket.getaddrinfo(host, 0, type=socket.SOCK_STREAM)[0]
    except OSError:
        return 0
    for _ in range(20):
        with (
            socket.socket(family, socket.SOCK_STREAM) as rctp,
            socket.socket(family, socket.SOCK_DGRAM) as data,
            socket.socket(family, socket.SOCK_STREAM) as files,
        ):
            try:
                rctp.bind(address)
                port: int = rctp.getsockname()[1]
                data.bind((address[0], port, *address[2:]))
                files.bind((address[0], port + FILES_PORT_OFFSET, *address[2:]))
            except OSError:  # taken, or past 65535: another
                continue
            return port
    return 0


async def _serve(
    make: Callable[[], ReferenceServer], tries: int, output: Output, ready_file: Path | None
) -> int:
    """Serve until a signal, once a server `make` makes could listen: on the ports it was
    given, or on another of `tries` free pairs when a port of the last was taken first."""
    for left in reversed(range(tries)):
        server = make()
        try:
            await server.start()
            break
        except OSError as exc:
            if left and exc.errno == errno.EADDRINUSE:
                continue
            output.problem("serve", _cannot_listen(server.settings, exc))
            return 2
    url = server.url
    settle()  # the process serves: fewer collector pauses under load (D-RCTP-32)
    _banner(server, output, url)
    # Signals are caught before the ready file says so: a script may send one at once.
    with Interrupts() as interrupts:
        if ready_file is not None and not _ready(ready_file, server, url, output):
            await server.stop()
            return 2
        try:
            await interrupts.wait()
            sessions = len(server.controls)
            output.notice(f"stopping: BYE to {plural(sessions, 'session')}")
            # A second Ctrl-C does not wait for the answers to BYE (up to 5 s, R-RCTP-23).
            stopped = await interrupts.race(_stop(server), count=2)
        finally:
            if ready_file is not None:
                ready_file.unlink(missing_ok=True)
    if not stopped:
        output.problem("serve", "stopped without waiting for the answers to BYE")
        return 1
    return 0


def _cannot_listen(settings: ServerSettings, exc: OSError) -> str:
    """One line naming every port tried: the error of a UDP bind does not say which it was."""
    # asyncio words a bind's error with the address; a host that does not resolve has a
    # negative errno (getaddrinfo's) and its own text.
    errno = exc.errno or 0
    reason = os.strerror(errno).lower() if errno > 0 else exc.strerror or str(exc)
    http = f" and {settings.http_port} (HTTP)" if settings.http_port is not None else ""
    return (
        f"cannot listen on {settings.host} port {settings.port} (RCTP, TCP and UDP){http}:"
        f" {reason}; choose other ports with --port and --http-port (0 picks free ones)"
    )


async def _stop(server: ReferenceServer) -> bool:
    await server.stop()
    return True


def _http_base(server: ReferenceServer) -> str | None:
    port = server.http_port
    return None if port is None else http_base(server.settings.host, port)


def _banner(server: ReferenceServer, output: Output, url: str) -> None:
    title = server.model.title or server.rcml.name
    rows = [("RCTP", url), ("data", f"UDP port {server.data_port}")]
    base = _http_base(server)
    if base is not None and server.files is not None:
        rows += [("files" if i == 0 else "", base + p) for i, p in enumerate(server.files.files)]
    output.err.line(
        [("serving ", ""), (title, "bold"), (f" with the {server.driver.name} driver", "")]
    )
    for label, text in rows:
        output.err.line([(f"  {label:<6}", "dim"), (text, "cyan")])
    output.err.line([("Ctrl-C to stop", "dim")])


def _ready(path: Path, server: ReferenceServer, url: str, output: Output) -> bool:
    base = _http_base(server)
    document = {"rctp": url, "data_port": server.data_port, "http": base and base + "/"}
    return write_ready(output, "serve", path, document)
