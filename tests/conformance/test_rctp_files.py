"""The robot's files over HTTP (D-RCTP-29) in a conformance run: the embedded reference serves
them where the spec puts them, on the TCP port after its RCTP port; the rctp/files cases pass on
it and on the independent server, are not applicable to a target whose ICS lacks `files`, and
fail on a files server that breaks R-RCTP-62 to R-RCTP-65, each naming what it breaks.

The faulty servers are files servers of the rover's real files on a real loopback socket, each
wrong in one way a reference mutant was (bench/mutation_survivors.md, files.py): one answer per
connection without `Connection: close`, a connection kept after `Connection: close`, a HEAD
answered with a body, a POST's 405 without the body its head promises, no RXID served, nothing
answered; and one serving another robot's RCML.
"""

from __future__ import annotations

import asyncio
import json
from pathlib import Path
from urllib.parse import urlsplit

import pytest
from support.foreign import IMPLEMENTATIONS
from support.processes import free_pair, run_command

from rcmlconf.conformance.ics import EVERYTHING
from rcmlconf.conformance.registry import all_cases, select
from rcmlconf.conformance.runner import RunOptions, run_cases
from rcmlconf.conformance.targets import REFERENCE, REFERENCE_RCML, Target, embedded_reference
from rcmlconf.reference.client.fetching import Deadline, fetch
from rcmlconf.reference.server.files import index_page, robot_files
from rcmlconf.validate.validator import load_robot

#: The longest a test's run may take (seconds).
BOUND = 60.0
CASES = "rctp/files/*"
INDEX, GET, HEAD, PERSISTENT = (
    f"rctp/files/{name}" for name in ("index", "get", "head", "persistent")
)
#: Another robot's RCML, served as the rover's by the `other-robot` fault.
CAMERA_RCML = REFERENCE / "camera" / "camera.rcml"
#: The files a faulty server gets wrong: what each case then says (verdict, requirement).
FAULTS: dict[str | None, dict[str, tuple[str, str | None]]] = {
    None: {},
    # Mutant 114 (`while False:`): every connection closed unanswered.
    "silent": {
        INDEX: ("fail", "R-RCTP-62"),
        GET: ("fail", "R-RCTP-62"),
        HEAD: ("fail", "R-RCTP-62"),
        PERSISTENT: ("fail", "R-RCTP-65"),
    },
    # Mutants 103: the connection closed after its first answer, which does not say so.
    "one-per-connection": {PERSISTENT: ("fail", "R-RCTP-65")},
    # Mutant 104 (`continue`): the connection kept after an answer to Connection: close.
    "kept-after-close": {PERSISTENT: ("fail", "R-RCTP-65")},
    # Mutant 130 (`>=`): a POST's 405 head with Content-Length 12 and no body, then the close.
    "unframed-405": {PERSISTENT: ("fail", "R-RCTP-65")},
    # Mutant 130 (`!=`): a HEAD answered with the body a GET gets.
    "head-body": {HEAD: ("fail", "R-RCTP-64"), PERSISTENT: ("fail", "R-RCTP-64")},
    # Mutant 58 (`is not`): the RXID file neither listed nor served.
    "no-rxid": {INDEX: ("fail", "R-RCTP-62"), GET: ("fail", "R-RCTP-63")},
    "other-robot": {
        INDEX: ("inconclusive", None),
        GET: ("fail", "R-RCTP-63"),
        HEAD: ("inconclusive", None),
    },
}


class FaultyFiles:
    """The rover's files over HTTP/1.1 (persistent connections, HEAD without a body), made
    wrong in the way `fault` names."""

    def __init__(self, fault: str | None) -> None:
        self.fault = fault
        files = robot_files(REFERENCE_RCML, load_robot(REFERENCE_RCML))
        self.files = {path: doc.data for path, doc in files.items()}
        if fault == "no-rxid":
            self.files = {p: data for p, data in self.files.items() if p.endswith(".rcml")}
        if fault == "other-robot":
            self.files["/rover.rcml"] = CAMERA_RCML.read_bytes()
        self.index = index_page("rover", {p: d for p, d in files.items() if p in self.files})

    async def handle(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        try:
            while self.fault != "silent":
                head = await asyncio.wait_for(reader.readuntil(b"\r\n\r\n"), 5.0)
                method, target = head.split(b" ", 2)[:2]
                closing = b"\r\nconnection: close\r\n" in head.lower()
                writer.write(self.answer(method, urlsplit(target.decode()).path, closing))
                await writer.drain()
                if closing and self.fault != "kept-after-close":
                    break
                if self.fault == "one-per-connection" or self.unframed(method):
                    break
        except (asyncio.IncompleteReadError, TimeoutError, ConnectionError):
            pass
        finally:
            writer.close()

    def unframed(self, method: bytes) -> bool:
        return self.fault == "unframed-405" and method not in (b"GET", b"HEAD")

    def answer(self, method: bytes, path: str, closing: bool) -> bytes:
        if method not in (b"GET", b"HEAD"):
            status, body, kind = b"405 Method Not Allowed", b"GET or HEAD\n", b"text/plain"
        elif path == "/":
            status, body, kind = b"200 OK", self.index, b"text/html; charset=utf-8"
        elif path in self.files:
            status, body, kind = b"200 OK", self.files[path], b"application/xml"
        else:
            status, body, kind = b"404 Not Found", b"not here\n", b"text/plain"
        fields = b"Content-Type: %s\r\nContent-Length: %d\r\n" % (kind, len(body))
        fields += b"Connection: close\r\n" if closing else b""
        sent = body if method != b"HEAD" or self.fault == "head-body" else b""
        sent = b"" if self.unframed(method) else sent
        return b"HTTP/1.1 " + status + b"\r\n" + fields + b"\r\n" + sent


async def verdicts_on(fault: str | None) -> dict[str, tuple[str, str | None]]:
    """The rctp/files cases against a target whose files (at its RCTP port + 1) are a faulty
    server's: each case's verdict and the requirement a failure names."""
    port = free_pair()
    files = FaultyFiles(fault)
    server = await asyncio.start_server(files.handle, "127.0.0.1", port + 1)
    robot = load_robot(REFERENCE_RCML)
    target = Target(
        server=("127.0.0.1", port),
        robot=robot,
        site_path=robot.site.path,
        features=EVERYTHING.features,
        name=f"files {fault}",
    )
    try:
        results = await run_cases(select(all_cases().values(), [CASES]), target, RunOptions())
    finally:
        server.close()
        await server.wait_closed()
    return {r.case: (r.verdict.value, r.requirement) for r in results}


@pytest.mark.parametrize("fault", list(FAULTS), ids=str)
def test_a_faulty_files_server_fails_the_case_of_what_it_breaks(fault: str | None) -> None:
    found = asyncio.run(asyncio.wait_for(verdicts_on(fault), BOUND))
    assert set(found) == {INDEX, GET, HEAD, PERSISTENT}
    wrong = {case: got for case, got in found.items() if got != ("pass", None)}
    assert wrong == FAULTS[fault]


def test_the_embedded_reference_serves_its_files_on_the_port_after_rctp() -> None:
    async def index() -> list[bytes]:
        async with embedded_reference(EVERYTHING.features) as target:
            assert target.server is not None
            host, port = target.server
            files = f"http://{host}:{port + 1}/"
            return await asyncio.gather(
                asyncio.to_thread(fetch, files, Deadline(5.0)),
                asyncio.to_thread(fetch, files + "rover.rxid", Deadline(5.0)),
            )

    page, rxid = asyncio.run(asyncio.wait_for(index(), BOUND))
    assert b'href="/rover.rcml"' in page
    assert b'href="/rover.rxid"' in page
    assert b"<rxid" in rxid


def test_the_cases_pass_on_the_embedded_reference_run_after_run(tmp_path: Path) -> None:
    report = tmp_path / "run.json"
    done = run_command("run", "--only", CASES, "--repeat", "2", "--json", str(report))
    results = json.loads(report.read_text())["results"]
    assert len(results) == 8
    assert {r["verdict"] for r in results} == {"pass"}, done.stdout
    assert all(not r.get("reason") for r in results), results  # all checked: the rover has RXID
    assert done.returncode == 0


def test_the_cases_are_not_applicable_to_a_target_without_files(tmp_path: Path) -> None:
    ics = tmp_path / "ics.toml"
    ics.write_text("[features]\nfiles = false\n")
    report = tmp_path / "run.json"
    done = run_command("run", "--ics", str(ics), "--only", CASES, "--json", str(report))
    results = json.loads(report.read_text())["results"]
    assert {r["verdict"] for r in results} == {"not applicable"}
    assert all("'files'" in r["reason"] for r in results)
    assert len(results) == 4
    assert done.returncode == 2  # nothing was tested


def test_the_independent_server_does_not_fail_them(tmp_path: Path) -> None:
    """It serves its RCML, links no RXID file, and closes each connection after one answer
    that says so (tests/foreign/rctp_server/main.py): every case passes, the RXID parts
    unchecked, and says so."""
    found = IMPLEMENTATIONS["rctp_server"].run_suite(tmp_path, only=[CASES])
    assert set(found.results) == {INDEX, GET, HEAD, PERSISTENT}, found.err
    assert set(found.having("pass")) == set(found.results), found.results
    assert "RXID" in found.having("pass")[INDEX]
