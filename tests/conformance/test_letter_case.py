"""A server that writes the grammar's tokens in other letter cases is not failed for it (D-RCTP-30,
R-RCTP-59): `Application/RCTP-Values`, `UDP;Client_Port=...;MODE=read`, `;TimeOut=60`,
`Reason: TIMEOUT` are the tokens the grammar spells out.

The embedded reference server is reached through a proxy that rewrites those tokens in what the
server sends (each the same length, so no Content-Length changes), and every server case runs
through it.
"""

from __future__ import annotations

from collections import Counter

from support.control_proxy import ControlProxy
from support.server_cases import server_cases_through

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


def test_tokens_in_other_letter_cases_fail_no_server_case() -> None:
    rewritten: Counter[bytes] = Counter()

    def rewrite(message: bytes) -> bytes:
        for old, new in REWRITES:
            rewritten[old] += message.count(old)
            message = message.replace(old, new)
        return message

    results = server_cases_through(lambda upstream: ControlProxy(upstream, rewrite=rewrite))
    assert not [(r.case, r.reason) for r in results if r.verdict is Verdict.FAIL]
    # The cases saw every rewritten token at least once: the test can fail.
    assert all(rewritten[old] for old, _ in REWRITES), rewritten
