"""rctp/stream/refused-stop (R-RCTP-66): a server's STOP answered 500 leaves the stream set up. It
passes on the embedded reference and on the independent server, and fails on the independent
server made to put the stream in `init` when it sends the STOP (its author's first reading of
D-RCTP-14, kept as its fault `stop-init-at-sending`), at the PAUSE after the refusal.
"""

from __future__ import annotations

import json
from pathlib import Path

from support.foreign import IMPLEMENTATIONS
from support.processes import run_command

CASE = "rctp/stream/refused-stop"


def test_it_passes_on_the_embedded_reference(tmp_path: Path) -> None:
    report = tmp_path / "run.json"
    done = run_command("run", "--only", CASE, "--json", str(report))
    results = json.loads(report.read_text())["results"]
    assert [(r["case"], r["verdict"]) for r in results] == [(CASE, "pass")], done.stdout
    assert done.returncode == 0


def test_the_independent_server_passes_and_fails_when_it_forgets_the_refused_stop(
    tmp_path: Path,
) -> None:
    server = IMPLEMENTATIONS["rctp_server"]
    correct = server.run_suite(tmp_path, only=[CASE])
    assert correct.having("pass") == {CASE: ""}, (correct.results, correct.err)
    faulty = server.run_suite(tmp_path, ["stop-init-at-sending"], only=[CASE])
    assert set(faulty.having("fail")) == {CASE}, (faulty.results, faulty.err)
    assert "expected PAUSE" in faulty.having("fail")[CASE]  # the first after the refused STOP
    assert faulty.status == 1
