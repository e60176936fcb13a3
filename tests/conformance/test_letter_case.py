"""A server that writes the grammar's tokens in other letter cases is not failed for it (D-RCTP-30,
R-RCTP-59): `Application/RCTP-Values`, `UDP;Client_Port=...;MODE=read`, `;TimeOut=60`,
`Reason: TIMEOUT` are the tokens the grammar spells out.

The embedded reference server is reached through a proxy that rewrites those tokens in what the
server sends (each the same length, so no Content-Length changes), and every server case runs
through it.
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
from collections import Counter

from rcmlconf.conformance.ics import EVERYTHING
from rcmlconf.conformance.registry import Role, all_cases
from rcmlconf.conformance.runner import RunOptions, run_cases
from rcmlconf.conformance.targets import embedded_reference
from rcmlconf.conformance.verdicts import Verdict

#: What the server writes, as a server of another letter case would write it.
REWRITES = (
    (b"Content-Type: application/rctp-values", b"Content-Type: Application/RCTP-Values"),
    (b"Content-Type: text/plain; charset=utf-8", b"Content-Type: Text/Plain; Charset=UTF-8"),
    (b";timeout=", b";TimeOut="),
    (b"Transport: udp;", b"Transport: UDP;"),
    (b"client_port=", b"Client_Port="),
    (b"mode=read", b"MODE=Read"),
    (b"Reason: timeout", b"Reason: TIMEOUT"),
)
#: The whole run, at most (seconds).
BOUND = 60.0


class CaseProxy:
    """A TCP proxy to `upstream` that rewrites REWRITES in the upstream's bytes."""

    def __init__(self, upstream: tuple[str, int]) -> None:
        self.upstream = upstream
        self.rewritten: Counter[bytes] = Counter()
        self._server: asyncio.Server | None = None

    async def start(self) -> tuple[str, int]:
        self._server = await asyncio.start_server(self._accepted, "127.0.0.1", 0)
        return self._server.sockets[0].getsockname()[:2]

    async def close(self) -> None:
        if self._server is not None:
            self._server.close()

    async def _accepted(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        try:
            up_reader, up_writer = await asyncio.open_connection(*self.upstream)
        except OSError:
            writer.close()
            return
        await asyncio.gather(
            self._pipe(reader, up_writer, rewrite=False),
            self._pipe(up_reader, writer, rewrite=True),
        )

    async def _pipe(
        self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter, rewrite: bool
    ) -> None:
        with contextlib.suppress(OSError, ConnectionError):
            while data := await reader.read(65536):
                if rewrite:
                    for old, new in REWRITES:
                        self.rewritten[old] += data.count(old)
                        data = data.replace(old, new)
                writer.write(data)
                await writer.drain()
        with contextlib.suppress(OSError, ConnectionError, RuntimeError):
            writer.close()


def test_tokens_in_other_letter_cases_fail_no_server_case() -> None:
    async def scenario() -> tuple[list[tuple[str, str]], Counter[bytes]]:
        async with embedded_reference(EVERYTHING.features) as target:
            assert target.server is not None
            proxy = CaseProxy(target.server)
            try:
                through = dataclasses.replace(target, server=await proxy.start())
                cases = [c for c in all_cases().values() if c.role is Role.SERVER]
                results = await run_cases(cases, through, RunOptions())
            finally:
                await proxy.close()
        failed = [(r.case, r.reason) for r in results if r.verdict is Verdict.FAIL]
        return failed, proxy.rewritten

    failed, rewritten = asyncio.run(asyncio.wait_for(scenario(), BOUND))
    assert not failed
    # The cases saw every rewritten token at least once: the test can fail.
    assert all(rewritten[old] for old, _ in REWRITES), rewritten
