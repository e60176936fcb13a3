"""The client cases on clients that do what D-RCTP-6 allows: send their own requests between the
server's request and its answer. Before, the harness took the client's READ for its answer
('expected a response; got Request(method='READ', ...)')."""

from __future__ import annotations

import asyncio

from rcmlconf.conformance.cases.rctp_client import answers
from rcmlconf.conformance.ics import EVERYTHING
from rcmlconf.conformance.probes.clients import ClientListener
from rcmlconf.conformance.registry import all_cases
from rcmlconf.conformance.runner import RunOptions, run_cases
from rcmlconf.conformance.targets import REFERENCE_RCML, Target
from rcmlconf.conformance.verdicts import Verdict
from rcmlconf.rcml.url import parse_rctp_url
from rcmlconf.rctp.connection import Connection, ProtocolFailure
from rcmlconf.rctp.errors import LocalProtocolError
from rcmlconf.rctp.states import Role as Side
from rcmlconf.rctp.states import SessionState
from rcmlconf.validate.validator import load_robot

BOUND = 60.0
#: How long each client stays, at most (the case ends it sooner).
LIFETIME = 10.0


def test_a_client_that_reads_before_it_answers_passes_the_client_cases() -> None:
    robot = load_robot(REFERENCE_RCML)
    readable = next(n.path for n in robot.data_nodes() if n.permission.name == "READ")
    interleaved: list[int] = []

    async def chatty_client(case_url: str) -> None:
        """CONNECT; then, whenever the server sends something, a READ of its own first, and
        only then what the core answers to it (the server's BYE, STOP, WRITE)."""
        url = parse_rctp_url(case_url)
        reader, writer = await asyncio.open_connection(url.host, url.port_or_default)
        loop = asyncio.get_running_loop()
        conn = Connection(Side.CLIENT, loop.time())
        conn.send_request("CONNECT", url.path, now=loop.time())
        try:
            deadline = loop.time() + LIFETIME
            while loop.time() < deadline and conn.session_state is not SessionState.CLOSED:
                writer.write(conn.data_to_send())
                data = await asyncio.wait_for(reader.read(65536), deadline - loop.time())
                if not data:
                    break
                if conn.session is None:  # CONNECT's answer, and what came after it
                    cut = data.find(b"\r\n\r\n") + 4
                    conn.receive_data(data[:cut], loop.time())
                    data = data[cut:]
                if conn.session is not None and data:
                    conn.send_request("READ", readable, now=loop.time())
                    interleaved.append(1)
                conn.receive_data(data, loop.time())
                events = list(iter(conn.next_event, None))
                if any(isinstance(e, ProtocolFailure) for e in events):
                    break  # R-RCTP-12: an answer that cannot be framed closes the connection
            writer.write(conn.data_to_send())
        except (OSError, TimeoutError, LocalProtocolError):
            pass
        finally:
            writer.close()

    async def scenario() -> list[tuple[str, Verdict, str]]:
        listener = ClientListener(robot, REFERENCE_RCML.read_bytes(), summon=chatty_client)
        await listener.start("127.0.0.1", 0)
        try:
            target = Target(clients=listener, features=EVERYTHING.features)
            # The cases of the server's own requests: the chatty client runs no scenario.
            cases = [c for c in all_cases().values() if c.run.__module__ == answers.__name__]
            results = await run_cases(cases, target, RunOptions())
        finally:
            await listener.close()
        return [(r.case, r.verdict, r.reason) for r in results]

    results = asyncio.run(asyncio.wait_for(scenario(), BOUND))
    assert interleaved, "the client never read before answering: the test did not interleave"
    assert {verdict for _, verdict, _ in results} == {Verdict.PASS}, results
