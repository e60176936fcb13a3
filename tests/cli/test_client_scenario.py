"""`rcmlconf client URL scenario` as a user runs it: real processes against `rcmlconf serve` of the
harness's robot, and a harness's case list over HTTP (D-RCTP-31)."""

from __future__ import annotations

import os
import select
import signal
import subprocess
import time
from contextlib import AbstractContextManager
from pathlib import Path

import pytest
from support.http_files import http_files
from support.processes import BOUND, COMMAND, Running, free_port, run_command, running
from support.robots import HARNESS

SCENARIO_ARGS = ("client", "--rcml", str(HARNESS))


def serve_harness(tmp_path: Path) -> AbstractContextManager[Running]:
    return running(tmp_path, "serve", "-v", "--port", "0", "--no-http", str(HARNESS))


def wait_for_log(server: Running, text: str) -> None:
    """Until the server's log (stdout) says `text`."""
    assert server.process.stdout is not None
    descriptor, seen = server.process.stdout.fileno(), b""
    deadline = time.monotonic() + BOUND
    while text.encode() not in seen:
        left = deadline - time.monotonic()
        assert left > 0, seen
        if select.select([descriptor], [], [], left)[0]:
            chunk = os.read(descriptor, 65536)
            assert chunk, seen
            seen += chunk


def cut_at_go(tmp_path: Path, *, stop_server: bool) -> tuple[str, int, str, str]:
    """The scenario on the harness's robot, cut once the server saw its first GO: the server
    stopped (BYE to every session) or Ctrl-C to the client. (case URL, status, stdout, stderr)"""
    with serve_harness(tmp_path) as server:
        url = str(server.ready["rctp"])
        client = subprocess.Popen(
            [*COMMAND, *SCENARIO_ARGS, url, "scenario"],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        try:
            wait_for_log(server, "GO /settings")
            if stop_server:
                server.stop(signal.SIGINT)  # BYE with Reason: shutdown
            else:
                client.send_signal(signal.SIGINT)
            out, err = client.communicate(timeout=BOUND)
        finally:
            client.kill()
    return url, client.returncode, out, err


def test_a_case_list_runs_each_case_in_turn_and_prints_a_line_a_run(tmp_path: Path) -> None:
    with serve_harness(tmp_path) as server:
        refused = f"rctp://127.0.0.1:{server.rctp_port}/no-such-case"
        case = f"rctp://127.0.0.1:{server.rctp_port}/harness"
        listing = f"{refused}\r\n{case}\n".encode()
        with http_files({"/cases": (listing, "text/plain")}) as http:
            list_url = f"http://127.0.0.1:{http.port}/cases"
            done = run_command(*SCENARIO_ARGS, list_url, "scenario")
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines() == [
        f"{refused}: CONNECT refused (404 Not Found)",
        f"{case}: completed",
    ]
    assert done.stderr == ""
    assert http.gets == ["/cases"]


def test_the_servers_bye_ends_a_run_which_still_counts_as_run(tmp_path: Path) -> None:
    url, status, out, err = cut_at_go(tmp_path, stop_server=True)
    assert (status, err) == (0, "")
    assert out == f"{url}: ended by the server (BYE, Reason: shutdown)\n"


def test_ctrl_c_ends_the_run_under_way_with_status_1(tmp_path: Path) -> None:
    url, status, out, err = cut_at_go(tmp_path, stop_server=False)
    assert (status, out) == (1, "")
    assert err == f"rcmlconf client: {url}: interrupted\n"


@pytest.mark.parametrize(
    ("url", "said"),
    [
        ("rctp://127.0.0.1:99999/case", "port '99999' is not between 1 and 65535"),
        ("ftp://127.0.0.1/cases", "(nor the http URL of a case list)"),
        ("http://127.0.0.1:0/cases", "is not a URL to fetch"),
        ("http://127.0.0.1:7331/ca\nses", "holds a control character"),
    ],
)
def test_a_bad_url_is_one_line_and_status_2(url: str, said: str) -> None:
    done = run_command(*SCENARIO_ARGS, url, "scenario")
    assert done.returncode == 2
    (line,) = [line for line in done.stderr.splitlines() if line.startswith("Error:")]
    assert line.startswith("Error: Invalid value for 'URL': "), done.stderr
    assert said in line
    assert "bug in rcmlconf" not in done.stderr


def test_a_list_that_cannot_be_fetched_is_one_line_and_status_2() -> None:
    url = f"http://127.0.0.1:{free_port()}/cases"
    done = run_command(*SCENARIO_ARGS, url, "scenario")
    assert done.returncode == 2
    assert done.stderr.startswith(f"rcmlconf client: cannot fetch {url}: ")
    assert len(done.stderr.splitlines()) == 1
    assert done.stdout == ""


@pytest.mark.parametrize(
    ("listing", "said"),
    [
        (b"rctp://127.0.0.1:1/a\nnot a url\n", "/cases', line 2: 'not a url' is not an RCTP URL"),
        (b"\n \n", "/cases' lists no case URL"),
        (b"rctp://127.0.0.1:1/\xff\n", "/cases' is not UTF-8 text (at offset 19)"),
        (
            b"rctp://127.0.0.1:1/a\n" * 10_001,
            "lists 10,001 case URLs; the client runs at most 10,000",
        ),
        (b"#" * (1024 * 1024 + 1), "/cases is larger than it may be (1,048,576 bytes)"),
    ],
    # Short IDs: a test's ID is in each child's environment (PYTEST_CURRENT_TEST), and one made
    # of a megabyte listing is past the kernel's bound on an environment string (E2BIG).
    ids=["not-a-url", "blank", "not-utf-8", "too-many", "too-large"],
)
def test_a_bad_case_list_is_one_line_and_status_2(listing: bytes, said: str) -> None:
    with http_files({"/cases": (listing, "text/plain")}) as http:
        done = run_command(*SCENARIO_ARGS, f"http://127.0.0.1:{http.port}/cases", "scenario")
    assert done.returncode == 2
    (line,) = done.stderr.splitlines()
    assert line.startswith("rcmlconf client: ")
    assert said in line


def test_help_teaches_the_scenario_and_both_url_forms() -> None:
    done = run_command("client", "URL", "scenario", "--help")
    assert done.returncode == 0
    text = " ".join(done.stdout.split())
    for taught in (
        "D-RCTP-31",
        "rctp://HOST:PORT/PATH",
        "http://HOST:PORT+1/cases",
        "rcmlconf run --role client --listen 7330",
    ):
        assert taught in text
