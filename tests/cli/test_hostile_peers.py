"""Our own clients against hostile peers on 127.0.0.1 (issue 27): `client`, `browse` and `run
--target` without --rcml fetch files from a port that trickles them or never ends them, and the
reference client meets a server that closes at once. Each command ends by itself, within its
deadline and a margin, with one clear line and a non-zero status; never a traceback.

The commands of a test run at once, each in its own process: what a test waits for is the
longest of them, not their sum."""

from __future__ import annotations

import asyncio
import subprocess
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass

from support.hostile_files import close_at_once, endless, rctp_and_files, tcp_peer, trickle
from support.processes import COMMAND
from support.robots import CAMERA

from rcmlconf.reference.client.adapter import Client, RctpError

#: The deadline the commands are given (--timeout, or the target wait of --timeout-scale 0.2).
DEADLINE = 1.0
#: What a command may take past its deadline: starting Python, a loaded machine. A command
#: still running after that hangs, and is killed.
MARGIN = 15.0
#: A trickle's pace: a byte each 0.2 s answers every wait of a client bounded per read.
PACE = 0.2


@dataclass(frozen=True)
class Hostile:
    """A command, and what it must end with."""

    args: tuple[str, ...]
    status: int
    says: str


def ended(commands: dict[str, Hostile]) -> None:
    """Run every command at once; each ends by itself, as it must."""
    started = {
        name: subprocess.Popen(
            [*COMMAND, *command.args], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
        )
        for name, command in commands.items()
    }
    failures: list[str] = []
    for name, process in started.items():
        try:
            _, err = process.communicate(timeout=DEADLINE + MARGIN)
        except subprocess.TimeoutExpired:
            process.kill()
            process.communicate()
            failures.append(f"{name}: still running after {DEADLINE + MARGIN:g} s")
            continue
        expected = commands[name]
        if "Traceback" in err or "internal error" in err:
            failures.append(f"{name}: {err}")
        elif process.returncode != expected.status or expected.says not in err:
            failures.append(f"{name}: exit {process.returncode}: {err!r}")
    assert not failures, "\n".join(failures)


@contextmanager
def files_peers() -> Iterator[dict[str, int]]:
    """A trickling and an endless files port, each at P+1 of a port P that accepts: P of each."""
    with ExitStack() as stack:
        yield {
            "trickle": stack.enter_context(rctp_and_files(trickle(PACE))),
            "endless": stack.enter_context(rctp_and_files(endless)),
        }


def test_client_browse_and_run_end_by_their_deadline_against_hostile_files() -> None:
    timeout = ("--timeout", f"{DEADLINE:g}")
    unfinished = "and did not finish"
    with files_peers() as port:

        def files(peer: str, path: str = "") -> str:
            return f"http://127.0.0.1:{port[peer] + 1}/{path}"

        def client(peer: str, *options: str) -> tuple[str, ...]:
            url = f"rctp://127.0.0.1:{port[peer]}/camera"
            return ("client", *options, url, "read", "/status/lens")

        ended(
            {
                "client, trickled index": Hostile(client("trickle", *timeout), 2, unfinished),
                "client, trickled --rcml": Hostile(
                    client("trickle", *timeout, "--rcml", files("trickle", "camera.rcml")),
                    2,
                    unfinished,
                ),
                # The size bounds what time would not: 16 MiB arrive long before 5 s.
                "client, endless index": Hostile(
                    client("endless", "--timeout", "5"), 2, "is larger than it may be"
                ),
                "browse, trickled panel": Hostile(
                    ("browse", *timeout, files("trickle", "panel.rxid")), 2, unfinished
                ),
                "run, trickled index": Hostile(
                    ("run", "--target", f"127.0.0.1:{port['trickle']}", "--timeout-scale", "0.2"),
                    2,
                    f"without --rcml: {files('trickle')} sent",
                ),
            }
        )


def test_the_client_against_a_server_that_closes_at_once_says_so() -> None:
    """Before, about 1 connection in 6 closed before the client set its socket's options,
    and the client crashed on the closed socket: "internal error: OSError: [Errno 9] Bad file
    descriptor". 200 tries catch that all but always."""

    async def tries(port: int) -> set[str]:
        said: set[str] = set()
        for _ in range(200):
            try:
                await Client.connect(f"rctp://127.0.0.1:{port}/camera", timeout=DEADLINE)
            except RctpError as error:
                said.add(str(error))
        return said

    with tcp_peer(close_at_once) as port:
        said = asyncio.run(tries(port))
        url = f"rctp://127.0.0.1:{port}/camera"
        read = ("client", "--rcml", str(CAMERA), url, "read", "/status/lens")
        ended({"client": Hostile(read, 2, "the server closed the connection")})
    assert said <= {
        "CONNECT /camera: not sent: the server closed the connection",
        "CONNECT /camera: no answer: the server closed the connection",
    }, said
