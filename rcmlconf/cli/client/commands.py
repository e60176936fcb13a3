"""`rcmlconf client URL COMMAND ...`: the click layer, and nothing else."""

from __future__ import annotations

from collections.abc import Callable
from typing import TypeVar

import click

from rcmlconf.cli.client.inputs import check_path, check_rcml
from rcmlconf.cli.client.live import plan_acquire
from rcmlconf.cli.client.requests import plan_read, plan_write
from rcmlconf.cli.client.running import Options, run, run_without_model
from rcmlconf.cli.client.scenario import run_cases
from rcmlconf.cli.client.stream import plan_stream
from rcmlconf.cli.client.watch import plan_watch
from rcmlconf.cli.console import Output
from rcmlconf.cli.params import DAY, seconds
from rcmlconf.errors import ValueTextError
from rcmlconf.rcml.paths import parse_node_path, parse_tree_path

#: --hold and --duration: a longer run is open-ended (leave the option out, stop with Ctrl-C).
_RUN = seconds(DAY)
#: --timeout: an answer that takes longer than an hour is not coming; Ctrl-C ends the wait.
_TIMEOUT = seconds(3600.0)
_P = TypeVar("_P", str, tuple[str, ...])


def _paths(parse: Callable[[str], str]) -> Callable[[click.Context, click.Parameter, _P], _P]:
    """A click callback that checks a path, or each of several, with `parse` (D-RCML-3), and
    that it fits in a request (D-RCTP-9)."""

    def check(ctx: click.Context, param: click.Parameter, value: _P) -> _P:
        try:
            if isinstance(value, str):
                return check_path(value, parse)
            return tuple(check_path(path, parse) for path in value)
        except ValueTextError as exc:
            raise click.BadParameter(str(exc)) from None

    return check


def _rcml(ctx: click.Context, param: click.Parameter, value: str | None) -> str | None:
    try:
        return None if value is None else check_rcml(value)
    except ValueTextError as exc:
        raise click.BadParameter(str(exc)) from None


_node_path = _paths(parse_node_path)
#: ACQUIRE also takes `/`, the whole tree (D-RCTP-26).
_tree_path = _paths(parse_tree_path)


@click.group()
@click.argument("url")
@click.option(
    "--rcml",
    metavar="PATH_OR_URL",
    callback=_rcml,
    help="The robot's RCML file, or its http(s) URL. Default: the one RCML file listed at "
    "http://HOST:PORT+1/, where the reference server serves the robot's files.",
)
@click.option(
    "--timeout",
    type=_TIMEOUT,
    default=5.0,
    show_default=True,
    metavar="S",
    help="Seconds to wait for the connection, each answer, and the RCML (its index and file"
    " together); at most an hour (a server that has not answered by then is not going to).",
)
@click.option(
    "--format",
    "output_format",
    type=click.Choice(["text", "json"]),
    default="text",
    show_default=True,
    help="text: name=value lines; json: one object (read) or one object a line (stream, watch,"
    " scenario).",
)
@click.pass_context
def client(
    ctx: click.Context, url: str, rcml: str | None, timeout: float, output_format: str
) -> None:
    """Talk RCTP/2.0 to a robot at URL (rctp://host[:port]/site-path) as the reference client;
    or run a conformance harness's client cases (`scenario`, which also takes its case list).

    Values are written and shown in their text form (D-RCML-14): decimal integers, floats
    such as 1.5, -2E3, INF or NaN, true/false, bytes in hexadecimal, an array's items
    separated by commas. The robot's RCML gives each node its type: pass it with --rcml, or
    let the client fetch it from the reference server's files.

    URL is at most 4,096 characters, and its path at most 4,079 bytes percent-encoded: CONNECT
    sends the path in a start line of at most 4,096 bytes (D-RCTP-9). Each segment of the path
    decodes to an XML Name (D-RCTP-7), and the host is an IP address or a DNS name.

    \b
    Exit status: 0 done;
      1 the server refused (`rcmlconf client: READ /x: 404 Not Found: no node /x`);
      2 usage error, no connection, no answer within --timeout, or no RCML.

    \b
    Examples:
      rcmlconf client rctp://127.0.0.1:7330/camera read /status/lens
      rcmlconf client rctp://127.0.0.1:7330/rover write /drive/settings maxSpeed=0.5 mode=1
      rcmlconf client rctp://127.0.0.1:7330/rover stream /sensors/odometry --duration 2
      rcmlconf client --format json rctp://127.0.0.1:7330/rover watch
      rcmlconf client http://127.0.0.1:7331/cases scenario
    """
    # URL is read when a subcommand runs, so that `rcmlconf client URL read --help` works.
    ctx.obj = Options(url, rcml, timeout, output_format == "json", Output())


@client.command(short_help="READ a data node or an event access.")
@click.argument("path", callback=_node_path)
@click.pass_obj
def read(options: Options, path: str) -> None:
    """READ the value of PATH: a data node, or an event access (all its readable nodes).

    A data node of an event access is read through its access (READ of the access with
    `Nodes:` naming it, D-RCTP-17). Prints `name = value` lines, or one JSON object.

    \b
    Examples:
      rcmlconf client rctp://127.0.0.1:7330/camera read /status/lens
      rcmlconf client rctp://127.0.0.1:7330/camera read /status/lens/model
    """
    run(options, lambda model: plan_read(options, model, path))


@client.command(short_help="WRITE a data node or an event access.")
@click.argument("path", callback=_node_path)
@click.argument("values", nargs=-1, required=True, metavar="VALUE | NAME=VALUE...")
@click.option(
    "--acquire/--no-acquire",
    default=True,
    show_default=True,
    help="ACQUIRE PATH first: writing needs the privilege (D-RCTP-16).",
)
@click.pass_obj
def write(options: Options, path: str, values: tuple[str, ...], acquire: bool) -> None:
    """WRITE a data node (one VALUE) or an event access (NAME=VALUE for each node to write).

    VALUE is the node's text form, taken as typed (`=` included); an array's items are
    separated by commas (`1,2,3`). The privilege ACQUIRE takes ends with the session, right
    after the write. A stream's nodes are written with `stream --mode write`.

    \b
    Examples:
      rcmlconf client rctp://127.0.0.1:7330/rover write /drive/settings maxSpeed=0.5 mode=1
      rcmlconf client rctp://127.0.0.1:7330/rover write /drive/settings/mode 2
    """
    run(options, lambda model: plan_write(options, model, path, values, acquire))


@client.command(short_help="ACQUIRE a path and hold it until Ctrl-C.")
@click.argument("path", callback=_tree_path)
@click.option(
    "--hold",
    type=_RUN,
    metavar="SECONDS",
    help="Release after this many seconds, at most a day. Default: hold until Ctrl-C.",
)
@click.pass_obj
def acquire(options: Options, path: str, hold: float | None) -> None:
    """ACQUIRE PATH (a node, or / for the whole robot) and hold it: no other session may write
    there until Ctrl-C or --hold SECONDS, then RELEASE and BYE.

    \b
    Example:
      rcmlconf client rctp://127.0.0.1:7330/rover acquire /drive --hold 60
    """
    run_without_model(options, plan_acquire(options, path, hold))


@client.command(short_help="Exchange a stream access's values on the data stream.")
@click.argument("path", callback=_node_path)
@click.option(
    "--mode",
    type=click.Choice(["read", "write", "both"]),
    default="read",
    show_default=True,
    help="read: the robot's values; write: --set values to the robot; both.",
)
@click.option(
    "--duration",
    type=_RUN,
    metavar="S",
    help="Stop after S seconds, at most a day. Default: run until Ctrl-C.",
)
@click.option(
    "--set",
    "assignments",
    multiple=True,
    metavar="NAME=VALUE",
    help="A value to write every interval (--mode write or both), for one or more writable"
    " nodes; the others are written as the robot has them.",
)
@click.pass_obj
def stream(
    options: Options, path: str, mode: str, duration: float | None, assignments: tuple[str, ...]
) -> None:
    """Exchange a stream access's values on the data stream (D-RCTP-18): SETUP, GO, one line
    per packet received (the robot's time of sending, then its values), STOP, BYE.

    Writing modes ACQUIRE the access first, then write the --set values every interval.
    Every writable node is written each time (D-RCTP-20): those --set does not name keep the
    robot's values, which the command reads first on the stream (a stream access has no READ,
    D-RCTP-17) and waits --timeout for; in --mode write it reads them in mode read, then PAUSE
    and SETUP change the stream to write (D-RCTP-28).

    The end prints a summary on stderr: packets received, lost, late and duplicated
    (D-RCTP-21), and the robot's clock offset (D-RCTP-24). A server's STOP or a lost stream is
    reported; a STOP or BYE from the server exits 1.

    \b
    Examples:
      rcmlconf client rctp://127.0.0.1:7330/rover stream /sensors/odometry --duration 5
      rcmlconf client rctp://127.0.0.1:7330/rover stream /drive/wheels --mode both \\
          --set left=0.2 --set right=0.2
      rcmlconf client rctp://127.0.0.1:7330/camera stream /stream/control --mode both \\
          --set pan=90 --duration 2
    """
    run(options, lambda model: plan_stream(options, model, path, mode, assignments, duration))


@client.command(short_help="Print the server's WRITE, STOP and BYE as they come.")
@click.argument("paths", nargs=-1, callback=_node_path, metavar="[PATH...]")
@click.option(
    "--duration",
    type=_RUN,
    metavar="S",
    help="Stop after S seconds, at most a day. Default: run until Ctrl-C or the server's BYE.",
)
@click.pass_obj
def watch(options: Options, paths: tuple[str, ...], duration: float | None) -> None:
    """Show the server's requests as they come: SETUP and GO event accesses (default: every one
    with a readable node), then print each data-change WRITE with its values (D-RCTP-27), each
    STOP, and the server's BYE with its Reason, one a line. GO sends nothing by itself
    (D-RCTP-27): `read` an access for its values now. The times are when each request
    arrived; the server's BYE ends the watch (exit 0).

    \b
    Examples:
      rcmlconf client rctp://127.0.0.1:7330/rover watch
      rcmlconf client rctp://127.0.0.1:7330/rover watch /drive/settings --duration 60
    """
    run(options, lambda model: plan_watch(options, model, paths, duration))


@client.command(short_help="Run the conformance scenario of a client (D-RCTP-31).")
@click.pass_obj
def scenario(options: Options) -> None:
    """Run the conformance scenario of a client (specs/rctp-2.0.md D-RCTP-31) on URL: what a
    conformance harness that plays the server asks of the client it tests, the same every time.

    \b
    The scenario, each step in the RCML's document order:
      1. fetch the robot's RCML: the one .rcml link of the index at http://HOST:PORT+1/PATH/
         (--rcml skips this step);
      2. CONNECT to PATH;
      3. READ every readable node of the normal accesses, then every event access;
      4. ACQUIRE / and WRITE each writable node what its READ gave (its zero value without r);
      5. each event access: SETUP, GO, the server's WRITEs for 1 s, PAUSE, WRITE, STOP;
      6. each stream access: SETUP, GO, 2 s, PAUSE, 0.5 s, GO, 1 s, STOP, with a heartbeat
         every second and DATA that sends the robot's own values back;
      7. WRITE the clock estimate to `offset` and `uncertainty` of a normal access `clock`;
      8. RELEASE *, BYE.

    A request the server refuses does not end a run (what needed it is left out); the server's
    BYE, the connection closing, or no answer within --timeout does. A run takes about 5 s on
    the harness's robot, and never much more than 30 s.

    URL is one case URL, rctp://HOST:PORT/PATH, or the harness's case list,
    http://HOST:PORT+1/cases (text/plain, one case URL a line; at most 10,000 URLs and 1 MiB),
    whose cases run one after the other. Each run prints one line: the case URL and how the run
    ended (`completed`; `ended by the server (BYE, Reason: timeout)`; `CONNECT refused (404 Not
    Found)`; ...), or with --format json one object with the requests that were refused too.
    The group's options come before URL: --rcml, --timeout (each wait for the server, 5 s as
    D-RCTP-31 says), --format.

    \b
    Exit status: 0 every run ran, whatever the server answered;
      1 Ctrl-C stopped the runs (the one under way says BYE first);
      2 a bad URL, a case list that cannot be fetched or read, or an --rcml that cannot be read.

    \b
    Examples:
      rcmlconf run --role client --listen 7330     # the harness, in one shell
      rcmlconf client http://127.0.0.1:7331/cases scenario   # its client cases, in another
      rcmlconf client rctp://127.0.0.1:7330/CASE scenario    # one case, by its URL
    """
    run_cases(options)
