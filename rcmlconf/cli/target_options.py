"""The options that say what is tested and how to reach it: `rcmlconf run`'s and `rcmlconf
fuzz`'s, declared once, read into one `TargetSettings`."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

import click

from rcmlconf.cli.hosts import address_option, listen_option
from rcmlconf.cli.params import Bounded
from rcmlconf.cli.run_options import site_option
from rcmlconf.conformance.run_defaults import CONNECT_TIMEOUT
from rcmlconf.conformance.settings import TargetSettings
from rcmlconf.rcml.url import DEFAULT_PORT as RCTP_PORT
from rcmlconf.reference.faults import Fault

#: D-RSP-9.
RSP_PORT = 7340
F = TypeVar("F", bound=Callable[..., Any])


def target_options(command: F) -> F:
    """Add the target options to a click command."""
    for option in reversed(_OPTIONS):
        command = option(command)
    return command


_OPTIONS = [
    click.option(
        "--target",
        metavar="HOST[:PORT]",
        callback=address_option(RCTP_PORT),
        help=f"An RCTP/2.0 server under test (port {RCTP_PORT} by default; IPv6 in brackets:"
        " [::1]:7330).",
    ),
    click.option(
        "--rcml",
        type=click.Path(exists=True, dir_okay=False, path_type=Path),
        help="The RCML file of --target's robot: the cases pick its nodes from it. With --role"
        " client: the robot the harness plays (default: its own, D-RCTP-31).",
    ),
    click.option(
        "--site",
        metavar="PATH",
        callback=site_option,
        help="--target's site path, the target of CONNECT (default: the RCML's).",
    ),
    click.option(
        "--rsp-target",
        metavar="HOST[:PORT]",
        callback=address_option(RSP_PORT),
        help=f"An RSP robot under test (port {RSP_PORT} by default); needs --model.",
    ),
    click.option(
        "--model",
        type=click.Path(exists=True, dir_okay=False, path_type=Path),
        help="The robot model (.rmodel) of --rsp-target, or of the robot the harness plays to the"
        " local system under test (--role local).",
    ),
    click.option(
        "--ics",
        type=click.Path(exists=True, dir_okay=False, path_type=Path),
        help="Implementation conformance statement (TOML): optional features the target lacks.",
    ),
    click.option(
        "--role",
        type=click.Choice(["server", "client", "local"]),
        default="server",
        show_default=True,
        help="client: the harness plays the server and tests the RCTP client that connects to"
        " --listen, once per case (reconnect it after each). local: the harness plays a robot of"
        " --model and tests the RSP local system that sends to --listen, one run of the scenario of"
        " specs/rsp.md D-RSP-24 per case (start it again after each).",
    ),
    click.option(
        "--listen",
        metavar="[HOST:]PORT",
        callback=listen_option("127.0.0.1"),
        help="With --role client or local: where the implementation under test connects or sends"
        " (127.0.0.1 by default).",
    ),
    click.option(
        "--client-command",
        metavar="'CMD {url}'",
        help="With --role client or local: start the implementation under test for each case, {url}"
        " replaced by the case's URL (client: rctp://HOST:PORT/<case id>, D-RCTP-31) or the address"
        " to send to (local: HOST:PORT). No shell reads it. It is stopped (its process group) when"
        " the case ends; its exit status and last lines of output are in the case's report. Without"
        " it, start your implementation yourself: a line says where each case waits.",
    ),
    click.option(
        "--connect-timeout",
        type=Bounded(0.1, 3600),
        default=CONNECT_TIMEOUT,
        show_default=True,
        metavar="SECONDS",
        help="With --role client or local: how long each case waits for its client to connect (or"
        " its local system's HELLO), before the case's own clock starts. Once a case got none while"
        " none had ever come, the rest give up at once (exit 2).",
    ),
    click.option(
        "--fault",
        "faults",
        multiple=True,
        type=click.Choice([f.value for f in Fault]),
        metavar="NAME",
        help="Without a target: make the embedded reference misbehave (see `rcmlconf serve --help`"
        " and `rcmlconf robot --help` for the names), to watch the suite catch it.",
    ),
]


def target_settings(options: dict[str, Any]) -> TargetSettings:
    """The target options, taken out of `options` (click's, by parameter name)."""
    return TargetSettings(
        target=options.pop("target"),
        rcml=options.pop("rcml"),
        site=options.pop("site"),
        rsp_target=options.pop("rsp_target"),
        model=options.pop("model"),
        ics=options.pop("ics"),
        role=options.pop("role"),
        listen=options.pop("listen"),
        client_command=options.pop("client_command"),
        connect_timeout=options.pop("connect_timeout"),
        faults=options.pop("faults"),
    )
