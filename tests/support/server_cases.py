"""The server cases run on the embedded reference server through a ControlProxy."""

from __future__ import annotations

import asyncio
import dataclasses
from collections.abc import Callable

from rcmlconf.conformance.ics import EVERYTHING
from rcmlconf.conformance.registry import all_cases
from rcmlconf.conformance.roles import Role
from rcmlconf.conformance.runner import RunOptions, run_cases
from rcmlconf.conformance.targets import Target, embedded_reference
from rcmlconf.conformance.verdicts import Result
from support.control_proxy import Address, ControlProxy

#: The whole run, at most (seconds).
BOUND = 90.0


def server_cases_through(
    proxy_of: Callable[[Address], ControlProxy], only: str = "rctp/"
) -> list[Result]:
    """Every server case whose ID starts with `only`, its control connections through the proxy
    `proxy_of` makes in front of the embedded reference server."""

    async def scenario() -> list[Result]:
        async with embedded_reference(EVERYTHING.features) as target:
            return await run_through(target, proxy_of, only)

    return asyncio.run(asyncio.wait_for(scenario(), BOUND))


async def run_through(
    target: Target, proxy_of: Callable[[Address], ControlProxy], *only: str
) -> list[Result]:
    """The server cases whose IDs start with one of `only`, run on `target` (an embedded
    reference) through the proxy `proxy_of` makes in front of its server."""
    assert target.server is not None
    proxy = proxy_of(target.server)
    try:
        # The proxy is a control connection's: the files, on the port after RCTP's
        # (D-RCTP-29), are not behind it, so their cases are not applicable here.
        through = dataclasses.replace(
            target, server=await proxy.start(), features=target.features - {"files"}
        )
        cases = [c for c in all_cases().values() if c.role is Role.SERVER and c.id.startswith(only)]
        return await run_cases(cases, through, RunOptions())
    finally:
        await proxy.close()
