"""D-RCTP-31's scenario, run by the reference client against `rcmlconf serve` of the harness's
robot: real processes and sockets, judged by what the server logged and answered."""

from __future__ import annotations

import asyncio
import re
from pathlib import Path

from support.http_files import files_after_free_port
from support.processes import run_command, running
from support.robots import HARNESS, robot

from rcmlconf.reference.client.scenario import Ending, run_scenario

#: The harness robot's normal data nodes, in document order.
NORMAL = [
    *(f"/values/all/{name}" for name in ("flag", "i8", "u8", "i16", "u16", "i32", "u32", "i64")),
    *(f"/values/all/{name}" for name in ("u64", "f32", "f64", "text", "blob", "triple", "level")),
    *("/clock/offset", "/clock/uncertainty"),
]
#: D-RCTP-31's steps 2 to 8 on the harness's robot, as the server logs them (BYE is not logged).
STEPS = [
    "CONNECT /harness",
    *(f"READ {path}" for path in NORMAL),
    "READ /settings",
    "ACQUIRE /",
    *(f"WRITE {path}" for path in NORMAL),
    "WRITE /settings",
    *("SETUP /settings", "GO /settings", "PAUSE /settings", "WRITE /settings", "STOP /settings"),
    *("SETUP /motion", "GO /motion", "PAUSE /motion", "GO /motion", "STOP /motion"),
    *("WRITE /clock/offset", "WRITE /clock/uncertainty", "RELEASE *"),
]
#: `serve -v`: `12:00:00.000 127.0.0.1:40000 READ /x -> 200 ...`.
_LOGGED = re.compile(r"\S+ (?P<peer>\S+) (?P<request>\S+ \S+) -> (?P<status>\d{3})")


def requests_of_first_session(log: str) -> list[tuple[str, str]]:
    """(request, status) of each request the first client's session made, in order."""
    found = [m for line in log.splitlines() if (m := _LOGGED.match(line))]
    assert found, log
    return [(m["request"], m["status"]) for m in found if m["peer"] == found[0]["peer"]]


def test_a_run_makes_every_step_in_order_and_writes_the_clock_estimate(tmp_path: Path) -> None:
    with running(tmp_path, "serve", "-v", "--port", "0", "--no-http", str(HARNESS)) as server:
        url = str(server.ready["rctp"])
        result = asyncio.run(run_scenario(url, model=robot(HARNESS)))
        assert (result.ending, result.refused) == (Ending.COMPLETED, ()), result
        assert str(result) == f"{url}: completed"
        read = run_command("client", "--rcml", str(HARNESS), url, "read", "/clock/uncertainty")
        _, log, _ = server.stop()
    assert requests_of_first_session(log) == [(step, "200") for step in STEPS]
    assert read.returncode == 0, read.stderr
    name, value = read.stdout.strip().split(" = ")
    # D-RCTP-24: never better than the robot's timePrecision, 1e-3; the node started at 0.
    assert name == "uncertainty"
    assert 1e-3 <= float(value) < 1.0


def test_step_1_reads_the_rcml_that_the_cases_index_links_to(tmp_path: Path) -> None:
    index = b'<html><body><a href="harness.rcml">the robot</a></body></html>'
    files = {
        "/harness/": (index, "text/html"),
        "/harness/harness.rcml": (HARNESS.read_bytes(), "application/xml"),
    }
    with files_after_free_port(files) as (port, http):
        serve = ("serve", "--port", str(port), "--no-http", str(HARNESS))
        with running(tmp_path, *serve):
            result = asyncio.run(run_scenario(f"rctp://127.0.0.1:{port}/harness"))
    assert result.ending is Ending.COMPLETED, result
    assert http.gets == ["/harness/", "/harness/harness.rcml"]


def test_an_index_without_one_rcml_link_ends_the_run_before_it_connects() -> None:
    files = {"/harness/": (b'<a href="a.rcml">a</a> <a href="b.rcml">b</a>', "text/html")}
    with files_after_free_port(files) as (port, _):
        result = asyncio.run(run_scenario(f"rctp://127.0.0.1:{port}/harness"))
    assert result.ending is Ending.NO_FILES, result
    assert f"http://127.0.0.1:{port + 1}/harness/ links to 2 RCML files, not one" in result.words


def test_connect_refused_ends_the_run(tmp_path: Path) -> None:
    with running(tmp_path, "serve", "-v", "--port", "0", "--no-http", str(HARNESS)) as server:
        url = f"rctp://127.0.0.1:{server.rctp_port}/no-such-case"
        result = asyncio.run(run_scenario(url, model=robot(HARNESS)))
        _, log, _ = server.stop()
    assert str(result) == f"{url}: CONNECT refused (404 Not Found)"
    assert requests_of_first_session(log) == [("CONNECT /no-such-case", "404")]


def test_a_run_is_cut_at_its_limit_and_its_session_ends(tmp_path: Path) -> None:
    with running(tmp_path, "serve", "-v", "--port", "0", "--no-http", str(HARNESS)) as server:
        url = str(server.ready["rctp"])
        # The steps' own waits take 4.5 s: a limit of 1 s always cuts the run.
        result = asyncio.run(run_scenario(url, model=robot(HARNESS), limit=1.0))
        _, log, _ = server.stop()
    assert str(result) == f"{url}: cut short (not over after 1 s)"
    requests = [request for request, _ in requests_of_first_session(log)]
    assert "RELEASE *" not in requests
    assert log.rstrip().endswith("session ended")
