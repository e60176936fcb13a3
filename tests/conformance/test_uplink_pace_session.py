"""rsp/session/uplink-pace judges the pace of its own session's UPLINKs (issue 27): a robot that
sends, beside each UPLINK of the session, one with another session's ID (a robot that forgot a
session it ended) keeps its session's pace; the case counted both, found them half a period
apart, and failed it or was inconclusive. The embedded reference, in this process, its sending
changed."""

from __future__ import annotations

import pytest
from support.embedded import run_embedded

from rcmlconf.conformance.verdicts import Verdict
from rcmlconf.reference.datagrams import Address, DataSocket
from rcmlconf.rsp.codec import PacketType
from rcmlconf.rsp.codec.header import SESSION_AT, TYPE_AT


@pytest.mark.parametrize("case", ["rsp/session/uplink-pace", "rsp/session/period"])
def test_uplinks_of_another_session_are_not_the_sessions_pace(
    monkeypatch: pytest.MonkeyPatch, case: str
) -> None:
    send = DataSocket.sendto

    def sendto(socket: DataSocket, data: bytes, addr: Address | None = None) -> None:
        send(socket, data, addr)
        if data[TYPE_AT] == PacketType.UPLINK:
            other = bytes(byte ^ 0xFF for byte in data[SESSION_AT : SESSION_AT + 6])
            send(socket, data[:SESSION_AT] + other + data[SESSION_AT + 6 :], addr)

    monkeypatch.setattr(DataSocket, "sendto", sendto)
    result = run_embedded(case)
    assert result.verdict is Verdict.PASS, result
