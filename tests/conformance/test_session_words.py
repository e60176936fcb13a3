"""A case that needs a session, against a server whose CONNECT is answered 200 without a Session
(D-RCTP-11), is inconclusive and says so: "CONNECT was answered 200 OK" alone named no fault."""

from __future__ import annotations

import re

from support.control_proxy import ControlProxy
from support.server_cases import server_cases_through

from rcmlconf.conformance.verdicts import Verdict

_SESSION = re.compile(rb"\r\nSession:[^\r]*", re.IGNORECASE)


def test_a_200_without_a_session_is_named() -> None:
    def rewrite(message: bytes) -> bytes:
        return _SESSION.sub(b"", message) if message.startswith(b"RCTP/2.0 200") else message

    (result,) = server_cases_through(
        lambda upstream: ControlProxy(upstream, rewrite=rewrite),
        only="rctp/value/canonical-order-read",
    )
    assert result.verdict is Verdict.INCONCLUSIVE, result
    assert result.reason == "CONNECT was answered 200 OK without a Session", result
