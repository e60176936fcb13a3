"""What is under test: the addresses and models a run's cases need, and the embedded reference
implementation started when no target is named (the README's main job)."""

from __future__ import annotations

import contextlib
import functools
import logging
import os
import socket
from collections.abc import AsyncIterator, Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from rcmlconf.conformance.probes.clients import HARNESS_RCML, ClientListener
from rcmlconf.conformance.probes.local_listener import LocalListener
from rcmlconf.conformance.probes.local_scenario import reference_local
from rcmlconf.rcml.model import RcmlDocument
from rcmlconf.rcml.url import FILES_PORT_OFFSET
from rcmlconf.reference.faults import Fault
from rcmlconf.rsp.codec import Encryption
from rcmlconf.rsp.model import RobotModel
from rcmlconf.rsp.security import KEY_SIZE

if TYPE_CHECKING:
    from rcmlconf.reference.server.adapter import ReferenceServer

Address = tuple[str, int]
REFERENCE = Path(__file__).resolve().parent.parent / "reference" / "robots"
#: The embedded reference's robots: the rover has every access type, CUBO is the paper's.
REFERENCE_RCML = REFERENCE / "rover" / "rover.rcml"
REFERENCE_RMODEL = REFERENCE / "cubo" / "cubo.rmodel"
#: The embedded server's session timeout (D-RCTP-11), short so the timeout cases are quick.
REFERENCE_SESSION_TIMEOUT = 2
#: Embedded RSP robots, so that RSP cases need not wait for each other's sessions.
REFERENCE_RSP_ROBOTS = 8
#: Ports the embedded reference tries before it gives up finding a free pair (`_paired`).
PAIR_TRIES = 20
MAX_PORT = 65535


@dataclass(frozen=True)
class Target:
    """The implementations under test. A role without its address is not under test."""

    #: An RCTP/2.0 server, its robot and its site path (D-RCTP-3). Its files, if it offers
    #: them, are on the port after `server`'s (D-RCTP-29).
    server: Address | None = None
    robot: RcmlDocument | None = None
    site_path: str = "/"
    #: RSP robots of one model, interchangeable: a case takes one for itself (`Context.rsp`), as
    #: a robot serves one session at a time (D-RSP-12). An external target is one robot.
    rsp: tuple[Address, ...] = ()
    rsp_model: RobotModel | None = None
    #: The RSP robots' pre-shared key (D-RSP-21), for the encrypted cases.
    rsp_psk: bytes | None = None
    #: Where RCTP/2.0 clients under test connect (the harness plays the server of `robot`).
    clients: ClientListener | None = None
    #: Where RSP local systems under test send (the harness plays a robot of `rsp_model`).
    locals: LocalListener | None = None
    #: The optional features the ICS declares (`ics.FEATURES`); every one by default.
    features: frozenset[str] = field(default_factory=frozenset)
    #: What the target is, for the report ("the embedded reference", "127.0.0.1:7330").
    name: str = "the target"


@contextlib.asynccontextmanager
async def embedded_reference(
    features: frozenset[str], faults: frozenset[Fault] = frozenset()
) -> AsyncIterator[Target]:
    """The reference RCTP server (the rover, its files on the port after RCTP's as D-RCTP-29
    says) and RSP robot (CUBO) on free loopback ports; `faults` (`reference.faults`) make them
    misbehave, to test the harness itself."""
    from rcmlconf.reference.drivers import choose_driver
    from rcmlconf.reference.faults import ROBOT_FAULTS, SERVER_FAULTS
    from rcmlconf.reference.rsp.robot import ReferenceRobot, RobotSettings
    from rcmlconf.reference.server.adapter import ReferenceServer, ServerSettings
    from rcmlconf.validate.validator import load_robot, load_robot_model

    robot = load_robot(REFERENCE_RCML)
    model = load_robot_model(REFERENCE_RMODEL)

    def server_on(port: int) -> ReferenceServer:
        settings = ServerSettings(
            port=port,
            http_port=port + FILES_PORT_OFFSET,  # D-RCTP-29, where a case looks for them
            session_timeout=REFERENCE_SESSION_TIMEOUT,
            faults=faults & SERVER_FAULTS,
        )
        return ReferenceServer(REFERENCE_RCML, robot, choose_driver("auto", robot), settings)

    psk = os.urandom(KEY_SIZE)
    robots = [
        ReferenceRobot(
            model,
            RobotSettings(
                port=0, encryptions=frozenset(Encryption), psk=psk, faults=faults & ROBOT_FAULTS
            ),
        )
        for _ in range(REFERENCE_RSP_ROBOTS)
    ]
    started: list[ReferenceRobot] = []
    played = load_robot(HARNESS_RCML)
    clients = ClientListener(played, HARNESS_RCML.read_bytes(), summon=reference_client)
    local = LocalListener(model, psk, summon=functools.partial(reference_local, model, psk))
    server = await _paired(server_on)
    try:
        await clients.start("127.0.0.1", 0)
        await local.start("127.0.0.1", 0)
        for rsp in robots:
            await rsp.start()
            started.append(rsp)
        yield Target(
            server=("127.0.0.1", server.port),
            robot=robot,
            site_path=robot.site.path,
            rsp=tuple(rsp.address for rsp in robots),
            rsp_model=model,
            rsp_psk=psk,
            clients=clients,
            locals=local,
            features=features,
            name="the embedded reference",
        )
    finally:
        for rsp in started:
            rsp.stop()
        await clients.close()
        await local.close()
        await server.stop()


async def _paired(server_on: Callable[[int], ReferenceServer]) -> ReferenceServer:
    """The reference server started on a free loopback port P (RCTP's TCP, its data stream's
    UDP) with its files on P+1 (D-RCTP-29): the kernel names a free port, and another is tried
    while P, or the port after it, is taken by the time the server binds them."""
    for _ in range(PAIR_TRIES):
        with socket.socket() as probe:
            probe.bind(("127.0.0.1", 0))
            port: int = probe.getsockname()[1]
        if port + FILES_PORT_OFFSET > MAX_PORT:
            continue
        server = server_on(port)
        try:
            await server.start()  # closes what it opened when a port is taken
        except OSError:
            continue
        return server
    raise OSError("no free pair of loopback ports for the embedded reference's RCTP and files")


def quiet_reference_logs() -> None:
    """Keep the embedded reference's own logs (a packet a case sent on purpose, dropped) out of
    a run's output: the verdicts say what happened. For commands and benches, not libraries."""
    quiet = logging.getLogger("rcmlconf")
    quiet.addHandler(logging.NullHandler())
    quiet.propagate = False


async def reference_client(url: str) -> None:
    """One reference client's run of D-RCTP-31's scenario on a case's URL."""
    from rcmlconf.reference.client.scenario import run_scenario

    await run_scenario(url)
