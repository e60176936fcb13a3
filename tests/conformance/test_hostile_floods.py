"""`rcmlconf run` against peers that flood it (issue 27): a robot that sends UPLINKs as fast as it
can, and a server whose data stream sends DATA as fast as it can. The run ends by itself, with
the verdict the flood earns (an UPLINK or DATA at an unbounded rate breaks the pace rules: fail,
not inconclusive, however long the harness's loop was held handling it, D-RSP-26, D-RCTP-33), and
its peak RSS stays under 150 MiB: the transcript keeps the first and the last of each flow and
says how many it left out."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from support.hostile_floods import CUBO, ROVER, flooding
from support.processes import COMMAND, measured

#: Peak RSS of `run` under any flood, at most (bytes).
MOST = 150 * 1024 * 1024


def _run(tmp_path: Path, *args: str) -> dict[str, Any]:
    report = tmp_path / "run.json"
    done = measured(*COMMAND, "run", *args, "--json", str(report))
    assert done.ended, "the run did not end by itself"
    assert "Traceback" not in done.stderr, done.stderr
    assert done.returncode == 1, (done.returncode, done.stderr[-2000:])
    assert done.peak < MOST, f"peak RSS {done.peak / 2**20:.0f} MiB"
    results: dict[str, Any] = {r["case"]: r for r in json.loads(report.read_text())["results"]}
    return results


def test_a_robot_flooding_uplinks_fails_the_pace_rules(tmp_path: Path) -> None:
    with flooding("robot") as port:
        results = _run(
            tmp_path,
            *("--rsp-target", f"127.0.0.1:{port}", "--model", str(CUBO)),
            *("--only", "rsp/session/uplink-pace", "--only", "rsp/session/keep-alive"),
            *("--only", "rsp/session/silence-keeps-session"),
        )
    for case in ("rsp/session/uplink-pace", "rsp/session/keep-alive"):
        assert (results[case]["verdict"], results[case]["requirement"]) == ("fail", "R-RSP-42")
    assert results["rsp/session/silence-keeps-session"]["verdict"] != "error"
    # The flood was one: the transcripts left datagrams out, and say how many.
    left = [gap for r in results.values() for gap in r["left_out"] if gap["what"] == "udp"]
    assert left, "no transcript left a datagram out: no flood"


def test_a_data_stream_flooding_data_fails_once_per_interval(tmp_path: Path) -> None:
    with flooding("stream") as port:
        results = _run(
            tmp_path,
            *("--target", f"127.0.0.1:{port}", "--rcml", str(ROVER)),
            *("--only", "rctp/stream/data-interval"),
        )
    found = results["rctp/stream/data-interval"]
    assert (found["verdict"], found["requirement"]) == ("fail", "R-RCTP-44")
