"""`rcmlconf client` refuses bad input with one line and status 2, before it connects (issue 15).

Each command runs as a real process against a listening socket on 127.0.0.1 that must never see
a connection: whatever the command line gets wrong is found before anything is sent.
"""

from __future__ import annotations

import asyncio
import http.server
import socket
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest
from support.processes import COMMAND, run_command
from support.robots import ROVER, TESTBOT
from support.servers import run, serving

#: Every wait of these tests is bounded by this many seconds.
BOUND = 20.0


@contextmanager
def listening() -> Iterator[str]:
    """`127.0.0.1:PORT` of a socket that listens; at the end, no one may have connected."""
    with socket.socket() as server:
        server.bind(("127.0.0.1", 0))
        server.listen()
        server.setblocking(False)
        yield f"127.0.0.1:{server.getsockname()[1]}"
        with pytest.raises(BlockingIOError):  # a connection would be waiting in the backlog
            server.accept()


def refused(*args: str) -> str:
    """`rcmlconf client ARGS`: status 2 and one error line, which is returned."""
    done = run_command("client", *args)
    assert done.returncode == 2, (done.stdout, done.stderr)
    assert done.stdout == ""
    assert "bug in rcmlconf" not in done.stderr, done.stderr
    errors = [line for line in done.stderr.splitlines() if line.startswith("Error: ")]
    assert len(errors) == 1, done.stderr
    assert len(errors[0]) < 400, errors[0]  # a line a person reads, however long the input
    return errors[0]


@pytest.mark.parametrize(
    ("url_path", "shown"),
    [
        ("/%00", r"'\x00' is not an XML Name"),  # item 1: was a traceback in data_received
        ("/rover/../../x", "'..' is not an XML Name"),
        ("/" + "a" * 70_000, "is 70,0"),  # item 4: was an internal error (start line)
    ],
)
def test_a_url_path_that_is_no_site_path_is_a_usage_error(url_path: str, shown: str) -> None:
    with listening() as address:
        error = refused("--rcml", str(ROVER), f"rctp://{address}{url_path}", "read", "/x/y")
    assert error.startswith("Error: Invalid value for 'URL': 'rctp://127.0.0.1:")
    assert shown in error


def test_a_site_path_too_long_for_connect_is_a_usage_error() -> None:
    # 4,096 characters in all, but CONNECT's start line would be 4,105 bytes (D-RCTP-9).
    error = refused("--rcml", str(ROVER), "rctp://h/" + "a" * 4_087, "read", "/x")
    assert error.startswith("Error: Invalid value for 'URL': 'rctp://h/aaa")
    assert "is 4,088 bytes percent-encoded; a request-target is at most 4,079 bytes" in error


@pytest.mark.parametrize(
    ("host", "shown"),
    [
        ("a" * 300, "is not a DNS name"),  # the resolver's UnicodeError was internal
        ("a..b", "'a..b' is not a DNS name"),
        ("a." * 130, "at most 253 characters"),
    ],
)
def test_a_host_no_resolver_takes_is_a_usage_error(host: str, shown: str) -> None:
    error = refused("--rcml", str(ROVER), f"rctp://{host}:7400/rover", "read", "/x")
    assert error.startswith("Error: Invalid value for 'URL': ")
    assert shown in error


def test_the_url_is_checked_when_the_subcommand_runs_so_its_help_works() -> None:
    done = run_command("client", "rctp://127.0.0.1:7400/%00", "read", "--help")
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith("Usage: rcmlconf client URL read [OPTIONS] PATH")


@pytest.mark.parametrize(
    ("rcml", "shown"),
    [
        ("http://[::1/x", "'http://[::1/x' is not a URL to fetch: Invalid IPv6 URL"),  # item 2
        ("http://", "'http://' is not a URL to fetch"),
        ("https://127.0.0.1:99999/r.rcml", "Port out of range"),
        ("http://127.0.0.1:port/r.rcml", "is not a URL to fetch"),
        ("", "'' is empty"),
        ("robot\n.rcml", "holds a control character"),
    ],
)
def test_a_bad_rcml_is_a_usage_error_naming_it(rcml: str, shown: str) -> None:
    with listening() as address:
        error = refused("--rcml", rcml, f"rctp://{address}/rover", "read", "/drive/settings")
    assert error.startswith("Error: Invalid value for '--rcml': ")
    assert shown in error


@pytest.mark.parametrize("text", ["inf", "1e309", "nan", "-inf", "0", "-1", "3600.5"])
def test_timeout_is_finite_and_at_most_an_hour(text: str) -> None:
    with listening() as address:
        error = refused(
            "--timeout", text, "--rcml", str(ROVER), f"rctp://{address}/rover", "read", "/x/y"
        )
    assert error.startswith("Error: Invalid value for '--timeout': ")
    assert ("not a finite number" in error) or ("0.0<x<=3600.0" in error)


@pytest.mark.parametrize(
    "args",
    [
        ["acquire", "/drive", "--hold", "nan"],  # item 5: held forever
        ["acquire", "/drive", "--hold", "inf"],
        ["acquire", "/drive", "--hold", "86401"],
        ["acquire", "/drive", "--hold", "0"],
        ["stream", "/sensors/odometry", "--duration", "nan"],
        ["stream", "/sensors/odometry", "--duration", "1e309"],
        ["stream", "/sensors/odometry", "--duration", "-2"],
        ["watch", "--duration", "nan"],
        ["watch", "--duration", "-inf"],
        ["watch", "--duration", "1e6"],
    ],
)
def test_every_duration_is_finite_and_at_most_a_day(args: list[str]) -> None:
    option = args[-2]
    with listening() as address:
        error = refused("--rcml", str(ROVER), f"rctp://{address}/rover", *args)
    assert error.startswith(f"Error: Invalid value for '{option}': ")
    assert ("not a finite number" in error) or ("0.0<x<=86400.0" in error)


@pytest.mark.parametrize(
    ("args", "shown"),
    [
        # A path the model does not know is read and acquired as given: it must fit a request.
        (["read", "/a" * 3_000], "6,000 characters long"),
        (["acquire", "/é" * 1_500], "10,500 bytes percent-encoded"),
        (["watch", "/b" * 40_000], "80,000 characters long"),
        (["read", "/%00"], "is not an XML Name"),
        (["acquire", ""], "paths are absolute"),
    ],
)
def test_a_path_that_fits_no_request_is_a_usage_error(args: list[str], shown: str) -> None:
    with listening() as address:
        error = refused("--rcml", str(ROVER), f"rctp://{address}/rover", *args)
    assert error.startswith("Error: Invalid value for ")
    assert shown in error


@pytest.mark.parametrize(
    ("args", "shown"),
    [
        (["write", "/drive/settings", "maxSpeed=" + "9" * 70_000], "too large for float32"),
        (["write", "/drive/settings/mode", "7" * 70_000], "outside the range of uint8"),
        (["write", "/drive/settings", "=1"], "has no data node ''"),
        (["write", "/drive/settings", "ma\x01x=1"], r"has no data node 'ma\x01x'"),
        (["stream", "/drive/wheels", "--mode", "both", "--set", "=1"], "has no data node ''"),
        (["stream", "/drive/wheels", "--mode", "write"], "give --set NAME=VALUE for one or more"),
        (["stream", "/sensors/odometry", "--mode", "write"], "has no node to write"),
    ],
)
def test_values_the_model_refuses_are_one_short_line(args: list[str], shown: str) -> None:
    with listening() as address:
        error = refused("--rcml", str(ROVER), f"rctp://{address}/rover", *args)
    assert shown in error


def test_a_set_of_a_read_only_node_is_a_usage_error() -> None:
    with listening() as address:
        error = refused(
            "--rcml",
            str(TESTBOT),
            f"rctp://{address}/testbot",
            "stream",
            "/drive/wheels",
            "--mode",
            "both",
            "--set",
            "odometry=1,2,3",
        )
    assert "(odometry is read-only)" in error


def test_a_node_left_out_that_cannot_be_read_is_a_usage_error(tmp_path: Path) -> None:
    rcml = tmp_path / "arm.rcml"
    rcml.write_text(
        '<?xml version="1.0" encoding="UTF-8"?>\n'
        '<rcml version="2.0" site="rctp://127.0.0.1/arm">\n'
        '  <group name="arm" permission="rw">\n'
        '    <access name="joints" type="stream" readInterval="0.02" writeInterval="0.02">\n'
        '      <data name="elbow" type="int16"/>\n'
        '      <data name="grip" type="int16" permission="w"/>\n'
        "    </access>\n"
        "  </group>\n"
        "</rcml>\n"
    )
    with listening() as address:
        error = refused(
            "--rcml", str(rcml), f"rctp://{address}/arm", "stream", "/arm/joints",
            "--mode", "both", "--set", "elbow=1",
        )  # fmt: skip
    assert "give --set grip=VALUE too" in error


class _Index(http.server.BaseHTTPRequestHandler):
    """A robot's files page (D-RCTP-29) whose one `.rcml` link is no URL."""

    def do_GET(self) -> None:
        page = b'<a href="http://[::1/robot.rcml">the robot</a>'
        self.send_response(200)
        self.send_header("Content-Length", str(len(page)))
        self.end_headers()
        self.wfile.write(page)

    def log_message(self, *args: object) -> None:
        """Quiet."""


@contextmanager
def files_page_next_to_a_listener() -> Iterator[str]:
    """`127.0.0.1:PORT` of a listening socket, with the page on PORT + 1, where the client looks."""
    for _ in range(20):
        with listening() as address:
            port = int(address.rsplit(":", 1)[1])
            try:
                page = http.server.HTTPServer(("127.0.0.1", port + 1), _Index)
            except OSError:  # taken: try another pair
                continue
            thread = threading.Thread(target=page.serve_forever, daemon=True)
            thread.start()
            try:
                yield address
            finally:
                page.shutdown()
                page.server_close()
                thread.join(BOUND)
            return
    raise AssertionError("no two free ports in a row")


def test_a_files_page_link_that_is_no_url_is_no_rcml_link() -> None:
    # urljoin raised ValueError on the server's link: an internal error.
    with files_page_next_to_a_listener() as address:
        done = run_command("client", f"rctp://{address}/robot", "read", "/a/b")
    assert done.returncode == 2
    assert done.stderr.startswith("rcmlconf client: http://127.0.0.1:")
    assert "links to 0 RCML files, not one; pass the robot's RCML with --rcml" in done.stderr
    assert len(done.stderr.splitlines()) == 1


# -- against the reference server --------------------------------------------------------------


async def finished(*args: str) -> tuple[int, str, str]:
    """`rcmlconf ARGS` as a process, to its end; the server runs in this test's loop."""
    process = await asyncio.create_subprocess_exec(
        *COMMAND, *args, stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE
    )
    out, err = await asyncio.wait_for(process.communicate(), BOUND)
    assert "Traceback" not in err.decode(), err.decode()
    return process.returncode or 0, out.decode(), err.decode()


@run
async def test_a_percent_encoded_site_path_is_decoded_before_connect() -> None:
    # `rov%65r` is `rover`: the client sent `/rov%2565r` and broke on the server's answer.
    async with serving(ROVER) as server:
        url = f"rctp://127.0.0.1:{server.port}/rov%65r"
        status, out, err = await finished(
            "client", "--rcml", str(ROVER), url, "read", "/identity/info/name"
        )
        assert (status, out, err) == (0, "name = rover\n", "")


@run
async def test_a_connect_answer_without_a_readable_session_is_the_servers_fault() -> None:
    """A server answering CONNECT 200 with an unreadable Session: one line naming R-RCTP-18,
    not an internal error (the client's core raised ValueTextError out of receive_data)."""

    async def answer(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        await reader.readuntil(b"\r\n\r\n")
        writer.write(b"RCTP/2.0 200 OK\r\nCSeq: 1\r\nSession: x\r\n\r\n")
        await writer.drain()
        await reader.read()  # until the client closes
        writer.close()

    server = await asyncio.start_server(answer, "127.0.0.1", 0)
    async with server:
        port = server.sockets[0].getsockname()[1]
        url = f"rctp://127.0.0.1:{port}/rover"
        status, out, err = await finished(
            "client", "--rcml", str(ROVER), url, "read", "/identity/info/name"
        )
    assert status != 0, (out, err)
    assert "bug in rcmlconf" not in err, err
    assert "R-RCTP-18" in err, err
    assert len(err.splitlines()) == 1, err
