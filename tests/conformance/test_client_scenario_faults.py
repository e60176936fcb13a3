"""rctp/client/stream-go-not-ok and rctp/client/refresh-connect on the reference client, which
passes, and on the reference client made wrong the way each case looks for: one that plays a
stream whose GO was not answered 200, one whose refresh CONNECT names its last ACQUIRE's target,
and one that never refreshes (inconclusive: D-RCTP-31 obliges no refresh)."""

from __future__ import annotations

import asyncio
from typing import Any

import pytest

from rcmlconf.conformance.ics import EVERYTHING
from rcmlconf.conformance.probes.clients import HARNESS_RCML, ClientListener
from rcmlconf.conformance.registry import all_cases
from rcmlconf.conformance.runner import RunOptions, run_cases
from rcmlconf.conformance.targets import Target, reference_client
from rcmlconf.conformance.verdicts import Result, Verdict
from rcmlconf.rcml.model import RcmlDocument
from rcmlconf.rctp.connection import Connection
from rcmlconf.rctp.messages import Request, Response
from rcmlconf.rctp.states import Role
from rcmlconf.reference.client import adapter
from rcmlconf.reference.client.session import ClientSession
from rcmlconf.validate.validator import load_robot

BOUND = 60.0
GO_NOT_OK = "rctp/client/stream-go-not-ok"
REFRESH = "rctp/client/refresh-connect"


class PlaysWhateverGoGot(ClientSession):
    """Plays a stream whatever its GO was answered (D-RCTP-31: only a 200 makes it play)."""

    def _answered(self, request: Request, response: Response, now: float) -> None:
        access = self._stream_access(request)
        if request.method == "GO" and response.status != 200 and access is not None:
            self._go(access, request, response, now)
        super()._answered(request, response, now)


class RefreshesLastAcquired(ClientSession):
    """Refreshes its session with a CONNECT of its last ACQUIRE's target, not the site path."""

    def send(self, method: str, path: str, *rest: Any, **named: Any) -> Request:
        if method == "ACQUIRE":
            self.site_path = path
        return super().send(method, path, *rest, **named)


class NeverRefreshes(ClientSession):
    """Takes its session's timeout for an hour, whatever CONNECT's answer said: no refresh."""

    def __init__(
        self, model: RcmlDocument | None, server_host: str, now: float, **settings: Any
    ) -> None:
        super().__init__(model, server_host, now, **settings)
        self.conn = Connection(Role.CLIENT, now, session_timeout=3600.0)


def _run(*case_ids: str) -> dict[str, Result]:
    """The cases on the reference client (as `adapter.ClientSession` is at the time)."""

    async def scenario() -> list[Result]:
        robot = load_robot(HARNESS_RCML)
        listener = ClientListener(robot, HARNESS_RCML.read_bytes(), summon=reference_client)
        await listener.start("127.0.0.1", 0)
        try:
            target = Target(clients=listener, features=EVERYTHING.features)
            cases = [all_cases()[case_id] for case_id in case_ids]
            return await run_cases(cases, target, RunOptions())
        finally:
            await listener.close()

    results = asyncio.run(asyncio.wait_for(scenario(), BOUND))
    return {result.case: result for result in results}


def test_the_reference_client_passes() -> None:
    results = _run(GO_NOT_OK, REFRESH)
    assert {c: r.verdict for c, r in results.items()} == {
        GO_NOT_OK: Verdict.PASS,
        REFRESH: Verdict.PASS,
    }, results


def test_a_client_that_plays_a_stream_whose_go_got_100_fails(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr(adapter, "ClientSession", PlaysWhateverGoGot)
    result = _run(GO_NOT_OK)[GO_NOT_OK]
    assert result.verdict is Verdict.FAIL, result
    assert result.requirement == "R-RCTP-44"
    assert "answered 100" in result.expected[0], result.expected
    assert "DATA payload" in (result.actual or ""), result.actual


def test_a_refresh_connect_of_another_path_fails(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(adapter, "ClientSession", RefreshesLastAcquired)
    result = _run(REFRESH)[REFRESH]
    assert result.verdict is Verdict.FAIL, result
    assert result.requirement == "R-RCTP-60"
    assert result.actual == "CONNECT /", result.actual


def test_a_client_that_never_refreshes_is_inconclusive(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(adapter, "ClientSession", NeverRefreshes)
    result = _run(REFRESH)[REFRESH]
    assert result.verdict is Verdict.INCONCLUSIVE, result
    assert "sent no CONNECT to refresh" in result.reason, result.reason
