"""`rcmlconf fuzz` beside boofuzz, against the same RCTP/2.0 server, in the same run (issue 29).

The embedded reference server runs as a process of its own, as `rcmlconf fuzz` starts it. Both
fuzzers drive it through the same request graph, CONNECT then ACQUIRE `/` then READ of a data
node, with the session's ID taken from CONNECT's answer. Each runs the same number of test cases,
rounds interleaved (the machine is shared), and the median of each is kept.

boofuzz runs at its fastest documented settings:
- no web interface (`web_port=None`) and no console logger (`fuzz_loggers=[]`);
- no sleep between cases (`sleep_time=0`);
- its case database keeps only the cases next to a failure (`fuzz_db_keep_only_n_pass_cases=1`);
- `recv_timeout=0.01` s: the shortest that still read every answer of this server here. The
  reference answers within a millisecond, and 0.005 s lost answers on a loaded machine.
boofuzz has no oracle but "the connection failed": it reads answers and judges none.

`rcmlconf fuzz` runs a whole campaign (`Campaign.run`): states, oracles, the state map, the
corpus, liveness probes; every state but `stop unanswered`, which waits out a receive timeout
(bench/fuzz_speed.py). Goal: at least 3 times boofuzz's cases a second.

    pip install boofuzz   # not a dependency of rcmlconf: the anchor only
    python bench/fuzz_vs_boofuzz.py [--cases 300] [--rounds 3] [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import re
import statistics
import tempfile
import time
from pathlib import Path
from typing import Any

from fuzz_speed import campaign  # this folder's: the same whole campaign

from rcmlconf.conformance.targets import REFERENCE_RCML
from rcmlconf.fuzz.launch import embedded_command, free_port, started
from rcmlconf.fuzz.rctp_cases import RctpCases
from rcmlconf.fuzz.rctp_robot import robot_paths
from rcmlconf.fuzz.rctp_target import RctpTarget
from rcmlconf.fuzz.seeds import control_seeds
from rcmlconf.validate.validator import load_robot

#: boofuzz's receive timeout, seconds (see the docstring).
RECV_TIMEOUT = 0.01
_SESSION = re.compile(rb"Session: ([^;\r]+)")


def boofuzz_graph(address: tuple[str, int], site: str, node: str, count: int, folder: Path) -> Any:
    """A boofuzz session of `count` cases over CONNECT of `site`, ACQUIRE and READ of `node`."""
    import boofuzz as bf

    if "CONNECT" not in bf.blocks.REQUESTS:  # boofuzz keeps its requests in one global table
        _define_requests(site, node)

    def with_session(target: Any, fuzz_data_logger: Any, session: Any, node: Any, **_: Any) -> Any:
        """The session's ID from the last answer, in place of SESSION (as a user would write)."""
        found = _SESSION.search(session.last_recv or b"")
        if found is None:
            return None
        return node.render().replace(b"SESSION", found.group(1))

    connection = bf.TCPSocketConnection(*address, send_timeout=1.0, recv_timeout=RECV_TIMEOUT)
    session = bf.Session(
        target=bf.Target(connection=connection),
        web_port=None,
        keep_web_open=False,
        fuzz_loggers=[],
        sleep_time=0,
        index_end=count,
        fuzz_db_keep_only_n_pass_cases=1,
        db_filename=f"{folder}.db",
        receive_data_after_each_request=True,
        receive_data_after_fuzz=True,  # read the fuzzed request's answer too
        restart_sleep_time=0,
    )
    session.connect(bf.s_get("CONNECT"))
    session.connect(bf.s_get("CONNECT"), bf.s_get("ACQUIRE"), callback=with_session)
    session.connect(bf.s_get("ACQUIRE"), bf.s_get("READ"), callback=with_session)
    return session


def _define_requests(site: str, node: str) -> None:
    """CONNECT of `site`, ACQUIRE `/` and READ of `node`, their fields fuzzable."""
    import boofuzz as bf

    bf.s_initialize("CONNECT")
    bf.s_string("CONNECT", name="method")
    bf.s_delim(" ", name="sp1")
    bf.s_string(site, name="target")
    bf.s_static(" RCTP/2.0\r\nCSeq: ")
    bf.s_string("1", name="cseq")
    bf.s_static("\r\n\r\n")

    bf.s_initialize("ACQUIRE")
    bf.s_string("ACQUIRE", name="method")
    bf.s_static(" / RCTP/2.0\r\nCSeq: 2\r\nSession: ")
    bf.s_string("SESSION", name="session")
    bf.s_static("\r\n\r\n")

    bf.s_initialize("READ")
    bf.s_string("READ", name="method")
    bf.s_delim(" ", name="sp1")
    bf.s_string(node, name="target")
    bf.s_static(" RCTP/2.0\r\nCSeq: 3\r\nSession: ")
    bf.s_string("SESSION", name="session")
    bf.s_static("\r\n\r\n")


#: The graph's paths: boofuzz fuzzes a node's every mutation before the next node's, so a
#: bounded run would fuzz only CONNECT. Each path gets a third of the cases instead.
PATHS = ("CONNECT", "CONNECT->ACQUIRE", "CONNECT->ACQUIRE->READ")


def boofuzz_round(
    address: tuple[str, int], site: str, node: str, count: int, folder: Path
) -> float:
    spent = 0.0
    for index, path in enumerate(PATHS):
        share = count // len(PATHS) + (index < count % len(PATHS))
        session = boofuzz_graph(address, site, node, share, folder / f"{index}")
        start = time.perf_counter()
        session.fuzz(name=path)
        spent += time.perf_counter() - start
    return spent


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cases", type=int, default=300)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    robot = load_robot(REFERENCE_RCML)
    paths = robot_paths(robot)
    made = RctpCases(paths, control_seeds())
    node = paths.readable.path if paths.readable is not None else "/"
    address = ("127.0.0.1", free_port())
    times: dict[str, list[float]] = {"boofuzz": [], "rcmlconf": []}
    with (
        started(embedded_command(address[1], ()), address, 10.0),
        tempfile.TemporaryDirectory() as out,
    ):
        target = RctpTarget(address, robot, paths.site, 5.0)
        for index in range(args.rounds):
            folder = Path(out) / str(index)
            folder.mkdir()
            times["boofuzz"].append(boofuzz_round(address, paths.site, node, args.cases, folder))
            times["rcmlconf"].append(campaign(target, made, args.cases, folder))
        target.close()
    rates = {name: args.cases / statistics.median(spent) for name, spent in times.items()}
    result = {
        "cases": args.cases,
        "rounds": args.rounds,
        "cpus": os.cpu_count(),
        "boofuzz_settings": {
            "web_port": None,
            "fuzz_loggers": [],
            "sleep_time": 0,
            "recv_timeout": RECV_TIMEOUT,
            "fuzz_db_keep_only_n_pass_cases": 1,
        },
        "cases_per_second": {name: round(rate, 1) for name, rate in rates.items()},
        "rcmlconf_vs_boofuzz": round(rates["rcmlconf"] / rates["boofuzz"], 2),
        "goal": 3.0,
    }
    if args.json:
        print(json.dumps(result, indent=1))
        return
    for name, rate in rates.items():
        print(f"{name:9} {rate:8.1f} cases/s (median of {args.rounds})")
    print(f"rcmlconf/boofuzz {result['rcmlconf_vs_boofuzz']:.2f} (goal >= 3)")


if __name__ == "__main__":
    main()
