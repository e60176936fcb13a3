"""One conformance case run in this process on the embedded reference (which a test may have
changed with a monkeypatch), bounded in time."""

from __future__ import annotations

import asyncio

from rcmlconf.conformance.ics import EVERYTHING
from rcmlconf.conformance.registry import all_cases
from rcmlconf.conformance.runner import RunOptions, run_cases
from rcmlconf.conformance.targets import embedded_reference
from rcmlconf.conformance.verdicts import Result

#: The whole run of one case, at most (seconds).
BOUND = 30.0


def run_embedded(case: str) -> Result:
    async def scenario() -> list[Result]:
        async with embedded_reference(EVERYTHING.features) as target:
            return await run_cases([all_cases()[case]], target, RunOptions())

    (result,) = asyncio.run(asyncio.wait_for(scenario(), BOUND))
    return result
