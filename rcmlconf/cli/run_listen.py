"""`run --role client` and `--role local`: the harness listens for the implementation under test
(it plays the server, or the robot), says where, starts the implementation for each case when
given `--client-command`, and otherwise says which case waits for it."""

from __future__ import annotations

import contextlib
from collections.abc import AsyncIterator
from dataclasses import dataclass
from pathlib import Path

import click

from rcmlconf.cli.console import Output
from rcmlconf.cli.hosts import Address
from rcmlconf.conformance.command import Command, CommandError
from rcmlconf.conformance.ics import Ics
from rcmlconf.conformance.probes.clients import ClientListener
from rcmlconf.conformance.probes.local_listener import LocalListener
from rcmlconf.conformance.targets import Target
from rcmlconf.rcml.model import RcmlDocument
from rcmlconf.rcml.url import http_base
from rcmlconf.rsp.model import RobotModel


@dataclass(frozen=True)
class ClientTarget:
    """--role client: where to listen, and the robot the harness serves."""

    listen: tuple[str, int]
    robot: RcmlDocument
    #: The file the robot was read from, served to the client as D-RCTP-31's step 1 says.
    rcml: Path
    features: frozenset[str]
    #: --client-command, started for each case.
    command: Command | None = None


@dataclass(frozen=True)
class LocalTarget:
    """--role local: where to listen, and the model of the robot the harness plays."""

    listen: tuple[str, int]
    model: RobotModel
    ics: Ics
    command: Command | None = None


def listen_command(template: str | None, listen: Address | None) -> Command | None:
    """--client-command, checked before anything starts."""
    if template is None:
        return None
    if listen is None:
        raise click.UsageError("--client-command is for --role client and --role local")
    try:
        return Command(template)
    except CommandError as error:
        raise click.BadParameter(str(error), param_hint="'--client-command'") from None


@contextlib.asynccontextmanager
async def client_target(external: ClientTarget, output: Output) -> AsyncIterator[Target]:
    """The harness listening for RCTP clients, as the run's target."""
    command = external.command
    waited: list[str] = []

    def waiting(case_id: str) -> None:
        waited.append(case_id)
        url = listener.url(case_id)
        output.notice(f"case {len(waited)} of {listener.runs}: waiting for a client at {url}")

    listener = ClientListener(
        external.robot,
        external.rcml.read_bytes(),
        summon=command,
        stop=None if command is None else command.stop,
        on_wait=waiting,
        owners=None if command is None else command.owners,
    )
    await listener.start(*external.listen)
    try:
        host, port = listener.address
        how = (
            f"each started as {command.template!r}"
            if command is not None
            else "start yours: it may loop over the list, or be started once per case URL"
        )
        output.notice(
            f"RCTP clients under test: one run of D-RCTP-31's scenario a case, at"
            f" rctp://{host}:{port}/<case id>; the case URLs in order at"
            f" {http_base(host, port + 1)}/cases; {how}"
        )
        yield Target(
            clients=listener,
            features=external.features,
            name=f"the client connecting to {host}:{port}",
        )
    finally:
        await listener.close()
        if command is not None:
            await command.close()


@contextlib.asynccontextmanager
async def local_target(external: LocalTarget, output: Output) -> AsyncIterator[Target]:
    """The harness playing a robot to an RSP local system, as the run's target."""
    command = external.command
    heard: list[None] = []

    def silent() -> None:
        heard.append(None)
        where = "{}:{}".format(*local.address)
        output.notice(f"case {len(heard)} of {local.runs}: waiting for a HELLO at {where}")

    local = LocalListener(
        external.model,
        external.ics.psk,
        summon=None if command is None else command.at,
        stop=None if command is None else command.stop,
        on_wait=silent,
    )
    await local.start(*external.listen)
    try:
        host, port = local.address
        how = f"started as {command.template!r}" if command is not None else "start it once a case"
        output.notice(
            f"RSP local system under test: one run of D-RSP-24's scenario a case, sending to"
            f" {host}:{port}; {how}"
        )
        yield Target(
            rsp_model=external.model,
            rsp_psk=external.ics.psk,
            locals=local,
            features=external.ics.features,
            name=f"the local system sending to {host}:{port}",
        )
    finally:
        await local.close()
        if command is not None:
            await command.close()
