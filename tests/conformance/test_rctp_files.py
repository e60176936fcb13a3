"""The robot's files over HTTP (D-RCTP-29) in a conformance run: the embedded reference serves
them where the spec puts them, on the TCP port after its RCTP port, where the cases look."""

from __future__ import annotations

import asyncio

from rcmlconf.conformance.ics import EVERYTHING
from rcmlconf.conformance.targets import embedded_reference
from rcmlconf.reference.client.files import fetch

#: The longest a test's run may take (seconds).
BOUND = 60.0


def test_the_embedded_reference_serves_its_files_on_the_port_after_rctp() -> None:
    async def index() -> tuple[bytes, bytes]:
        async with embedded_reference(EVERYTHING.features) as target:
            assert target.server is not None
            host, port = target.server
            files = f"http://{host}:{port + 1}/"
            return await asyncio.gather(
                asyncio.to_thread(fetch, files, 5.0),
                asyncio.to_thread(fetch, files + "rover.rxid", 5.0),
            )

    page, rxid = asyncio.run(asyncio.wait_for(index(), BOUND))
    assert b'href="/rover.rcml"' in page
    assert b'href="/rover.rxid"' in page
    assert b"<rxid" in rxid
