"""One client command: the model, a session, the command's work, and the exit status.

Every command runs the same way: find the model, connect (CONNECT), do the work, say BYE, and
turn what went wrong into one line on stderr and an exit status, as every rcmlconf command does:
0 done; 1 the server refused (an error status, or an answer the client cannot use); 2 usage or
the environment (no model, no connection, no answer in time).
"""

from __future__ import annotations

import asyncio
import sys
from collections.abc import Awaitable, Callable, Coroutine
from dataclasses import dataclass
from typing import Any, NoReturn

import click

from rcmlconf.cli.client.inputs import check_url
from rcmlconf.cli.console import Output
from rcmlconf.errors import ValueTextError
from rcmlconf.rcml.model import RcmlDocument
from rcmlconf.rcml.url import RctpUrl
from rcmlconf.reference.client.adapter import Client, RctpError
from rcmlconf.reference.client.fetching import Deadline
from rcmlconf.reference.client.files import NoModel, load_model

#: What a command does in its session; its exit status.
Work = Callable[[Client], Awaitable[int]]
#: R-RCTP-23: the side that sends BYE closes the connection after 5 seconds without an answer.
BYE_WAIT = 5.0


@dataclass(frozen=True, slots=True)
class Options:
    """The group's options, which every subcommand shares."""

    #: As typed: read by `run`, so that a subcommand's --help needs no valid URL.
    url: str
    rcml: str | None
    timeout: float
    json: bool
    output: Output


def run(options: Options, plan: Callable[[RcmlDocument], Work]) -> NoReturn:
    """Load the model, let `plan` check the command line against it (raising click's usage
    errors), then do the work in a session and exit with its status."""

    def start() -> Coroutine[Any, Any, int]:
        url = _url(options)
        model = load_model(url, options.rcml, Deadline(options.timeout))
        return _session(url, options, model, plan(model))

    _finish(options.output, start)


def run_without_model(options: Options, work: Work) -> NoReturn:
    """For work that carries no values (ACQUIRE): no RCML is looked for, so none can be missing."""
    _finish(options.output, lambda: _session(_url(options), options, None, work))


def _finish(output: Output, start: Callable[[], Coroutine[Any, Any, int]]) -> NoReturn:
    try:
        status = asyncio.run(start())
    except NoModel as exc:
        output.problem("client", str(exc))
        status = 2
    except RctpError as exc:
        output.problem("client", str(exc))
        status = 1 if exc.response is not None else 2
    sys.exit(status)


def _url(options: Options) -> RctpUrl:
    try:
        return check_url(options.url)
    except ValueTextError as exc:
        raise click.BadParameter(str(exc), param_hint="'URL'") from None


async def _session(url: RctpUrl, options: Options, model: RcmlDocument | None, work: Work) -> int:
    client = await Client.connect(url, model, timeout=options.timeout)
    try:
        return await work(client)
    finally:
        await client.close(min(options.timeout, BYE_WAIT))
