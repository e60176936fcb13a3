"""The server cases the MUST-by-MUST audit added or tightened (bench/audit_rctp_server.md): each
passes the reference server and the independent one of tests/foreign/rctp_server, and fails a
reference server made to make the fault it is aimed at, naming the requirement that fault breaks.
The faulty server is a copy of the package with one line changed (`mutated`), served in its own
process; the harness that judges it is the installed one. Real processes on loopback."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest
from support.foreign import IMPLEMENTATIONS
from support.mutants import mutated
from support.processes import BOUND, COMMAND, run_command
from support.robots import ROVER

UNREADABLE = Path(__file__).parent / "robots" / "unreadable.rcml"
READS = ["rctp/node/read-unreadable", "rctp/node/read-event-unreadable"]
KEPT = "rctp/session/stream-keeps-alive"
FLOORS = "rctp/session/peer-floors"
#: The served session timeout, short enough for KEPT to wait out (the embedded reference's too).
SESSION_TIMEOUT = "2"
#: (module under rcmlconf/, the line, the line as the fault reads, the robot served, the cases,
#: the requirement they must fail naming).
FAULTS = {
    # A server that checks the permission of WRITE only.
    "permission-of-write-only": (
        "reference/server/session.py",
        "        if needed not in node.permission:",
        "        if needed is Permission.WRITE and needed not in node.permission:",
        UNREADABLE,
        READS,
        "R-RCTP-27",
    ),
    # A server that asks for the privilege of mode=write, not of mode=both.
    "privilege-of-mode-write-only": (
        "reference/server/session.py",
        "        if Direction.WRITE in directions:\n            for node in access.writable():",
        '        if transport.mode == "write":\n            for node in access.writable():',
        ROVER,
        ["rctp/stream/setup-write-not-acquired"],
        "R-RCTP-34",
    ),
    # A receiver that compares sequence numbers as integers, not modulo 65,536.
    "plain-sequence-comparison": (
        "rctp/datastream/order.py",
        "        if 1 <= ahead <= _MAX_AHEAD:  # D-RCTP-21, RFC 1982",
        "        if sequence > (highest & _MASK):",
        ROVER,
        ["rctp/stream/stale-data-ignored"],
        "R-RCTP-43",
    ),
    # A receiver that measures a head only once its empty line has come.
    "head-measured-at-its-end": (
        "rctp/reader.py",
        "        if line_end >= 0 and len(buffer) - line_end - 2 > self.limits.header_section + 4:",
        "        if False:",
        ROVER,
        ["rctp/msg/header-section-unbounded"],
        "R-RCTP-16",
    ),
    # A server that times a session by its requests alone, not by its data-stream packets.
    "packets-keep-no-session": (
        "rctp/connection.py",
        'it keeps the session alive (D-RCTP-11)."""\n        self._last_activity = now',
        'it keeps the session alive (D-RCTP-11)."""',
        ROVER,
        [KEPT],
        "R-RCTP-21",
    ),
    # A server that compares the whole Session field with the session's ID.
    "session-field-compared-whole": (
        "rctp/request_checks.py",
        "        named = parse_session(given).id",
        "        named = given",
        ROVER,
        ["rctp/session/session-with-timeout"],
        "R-RCTP-19",
    ),
    # A receiver that takes a header line it cannot parse for a field it does not know.
    "bad-header-line-skipped": (
        "rctp/reader.py",
        "            if not colon or _TOKEN.fullmatch(name) is None:",
        "            if False:",
        ROVER,
        ["rctp/msg/bad-header-line"],
        "R-RCTP-8",
    ),
    # A server that checks the Nodes of a READ and takes a WRITE's as listed.
    "write-nodes-as-listed": (
        "reference/server/session.py",
        "            names = parse_nodes(text)",
        "            names = parse_nodes(text) if needed is Permission.READ else"
        ' [n.strip() for n in text.split(",")]',
        ROVER,
        ["rctp/node/write-event-nodes-order", "rctp/node/write-event-nodes-repeated"],
        "R-RCTP-30",
    ),
    # A reader that takes a bare LF for CRLF in an answer to the server's own request.
    "bare-lf-answer-taken": (
        "rctp/reader.py",
        "        self._buffer += data\n",
        '        self._buffer += re.sub(rb"(?<!\\r)\\n", b"\\r\\n", data)'
        ' if data.startswith(b"RCTP/") else data\n',
        ROVER,
        ["rctp/msg/response-unframeable"],
        "R-RCTP-12",
    ),
    # A reader that takes a status code by its class digit (`2x0` for a 200): ALSO has the rest.
    "status-read-by-its-class": (
        "rctp/reader.py",
        '_STATUS = re.compile(rb"[0-9]{3}")',
        '_STATUS = re.compile(rb"[0-9][0-9A-Za-z]{2}")',
        ROVER,
        ["rctp/msg/response-unframeable"],
        "R-RCTP-12",
    ),
    # A receiver that reads `timeout` in Session as written, not in any letter case.
    "session-timeout-as-written": (
        "rctp/fields.py",
        "(?:;[ \\t]*(?ai:timeout)=",
        "(?:;[ \\t]*timeout=",
        ROVER,
        ["rctp/session/session-with-timeout"],
        "R-RCTP-59",
    ),
    # A server that serves 8 sessions of one address, below R-RCTP-67's floor of 32.
    "sessions-capped-at-8": (
        "reference/server/limits.py",
        "    sessions_per_peer: int = 64\n",
        "    sessions_per_peer: int = 8\n",
        ROVER,
        [FLOORS],
        "R-RCTP-67",
    ),
    # A server that refuses a CONNECT beyond its cap of sessions with 500, not 503.
    "session-cap-answered-500": (
        "reference/server/session.py",
        '                raise Refused(503, f"{cap} sessions',
        '                raise Refused(500, f"{cap} sessions',
        ROVER,
        [FLOORS],
        "R-RCTP-67",
    ),
    # A reader that takes the grammar's "RCTP/" as case-sensitive: rctp/2.0 answered 400.
    "version-parsed-case-sensitively": (
        "rctp/reader.py",
        '_VERSION = re.compile(rb"(?i:RCTP)/[0-9]+\\.[0-9]+")',
        '_VERSION = re.compile(rb"RCTP/[0-9]+\\.[0-9]+")',
        ROVER,
        ["rctp/msg/wrong-version"],
        "R-RCTP-10",
    ),
}
#: More (line, line as the fault reads) some faults change in their module.
ALSO = {
    "status-read-by-its-class": [
        (
            "            return Response(int(parts[1]), parts[2]",
            "            return Response(int(parts[1][:1]) * 100, parts[2]",
        )
    ],
}


@contextmanager
def served(tmp_path: Path, rcml: Path, python: Path | None = None) -> Iterator[str]:
    """`rcmlconf serve RCML` on free ports, from the package copied into `python` if given: its
    RCTP address."""
    ready = tmp_path / f"serve-{time.monotonic_ns()}.json"
    command = [sys.executable, "-m", "rcmlconf"] if python is not None else COMMAND
    env = {**os.environ, "PYTHONPATH": str(python)} if python is not None else None
    ports = ["--port", "0", "--http-port", "0", "--ready-file", str(ready)]
    timeout = ["--session-timeout", SESSION_TIMEOUT]
    process = subprocess.Popen(
        [*command, "serve", str(rcml), *ports, *timeout],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        cwd=python,
        env=env,
    )
    try:
        deadline = time.monotonic() + BOUND
        while not ready.exists():
            assert process.poll() is None, process.communicate()
            assert time.monotonic() < deadline, "the server never said it was ready"
            time.sleep(0.02)
        url = str(json.loads(ready.read_text())["rctp"])
        yield "127.0.0.1:" + url.rsplit(":", 1)[1].split("/")[0]
    finally:
        process.kill()
        _, err = process.communicate(timeout=BOUND)
        assert "Traceback" not in err, err


def judged(
    tmp_path: Path, address: str, rcml: Path, cases: list[str]
) -> dict[str, tuple[str, str]]:
    """The installed harness's verdict on each case, and the requirement it names."""
    report = tmp_path / f"run-{time.monotonic_ns()}.json"
    chosen = [arg for case in cases for arg in ("--only", case)]
    run_command("run", "--target", address, "--rcml", str(rcml), *chosen, "--json", str(report))
    results = json.loads(report.read_text())["results"]
    return {r["case"]: (r["verdict"], r["requirement"]) for r in results}


@pytest.mark.parametrize("fault", sorted(FAULTS))
def test_each_case_passes_the_reference_and_fails_its_fault(tmp_path: Path, fault: str) -> None:
    module, line, faulty, rcml, cases, requirement = FAULTS[fault]
    with served(tmp_path, rcml) as address:
        right = judged(tmp_path, address, rcml, cases)
    assert {case: verdict for case, (verdict, _) in right.items()} == dict.fromkeys(cases, "pass")
    copy = mutated(tmp_path, module, (line, faulty), *ALSO.get(fault, []))
    with served(tmp_path, rcml, copy) as address:
        wrong = judged(tmp_path, address, rcml, cases)
    assert wrong == dict.fromkeys(cases, ("fail", requirement)), wrong


def test_the_independent_server_passes_them(tmp_path: Path) -> None:
    """Its robot has nodes without r in a normal and an event access, so none is not applicable.
    Its sessions last 60 s, which KEPT waits out only when told --session-wait 60 (a minute)."""
    cases = sorted({case for *_, named, _ in FAULTS.values() for case in named} - {KEPT})
    found = IMPLEMENTATIONS["rctp_server"].run_suite(tmp_path, only=cases)
    assert {case: verdict for case, (verdict, _) in found.results.items()} == dict.fromkeys(
        cases, "pass"
    ), found.results
