"""`run --role client|local --client-command 'CMD {url}'` and `--connect-timeout`: the harness
starts the implementation under test once per case and reports how it ran; without a command it
says where each case waits, and a run with no client gives up after its first case (issue 17)."""

from __future__ import annotations

import json
import shlex
import sys
from pathlib import Path

from support.foreign import FOREIGN
from support.processes import COMMAND, free_pair, run_command

ONE_CASE = ("--only", "rctp/client/connect-first")
TWO_CASES = (*ONE_CASE, "--only", "rctp/client/answers-bye")


def _results(report: Path) -> dict[str, dict[str, object]]:
    return {r["case"]: r for r in json.loads(report.read_text())["results"]}


def test_the_reference_client_started_per_case_passes_and_the_banner_says_where(
    tmp_path: Path,
) -> None:
    port = free_pair()
    report = tmp_path / "run.json"
    # A client that takes 2 s to start: more than a third of a case's 5 s, which the case's
    # clock no longer counts (the wait is --connect-timeout's).
    slow = tmp_path / "slow_client.py"
    slow.write_text(
        "import os, sys, time\n"
        "time.sleep(2)\n"
        f"command = {[*COMMAND, 'client']!r} + [sys.argv[1], 'scenario']\n"
        "os.execv(command[0], command)\n"
    )
    command = shlex.join([sys.executable, str(slow)]) + " {url}"
    done = run_command(
        "run", "--role", "client", "--listen", str(port), *TWO_CASES,
        "--client-command", command, "--json", str(report),
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert f"rctp://127.0.0.1:{port}/<case id>" in done.stderr
    assert f"http://127.0.0.1:{port + 1}/cases" in done.stderr
    assert "waiting for a client" not in done.stderr  # the harness starts them itself
    assert {r["verdict"] for r in _results(report).values()} == {"pass"}


def test_a_client_that_exits_before_connecting_is_inconclusive_with_its_output(
    tmp_path: Path,
) -> None:
    port = free_pair()
    report = tmp_path / "run.json"
    crash = [sys.executable, "-c", "import sys; print('cannot start for', sys.argv[1]); exit(3)"]
    done = run_command(
        "run", "--role", "client", "--listen", str(port), *ONE_CASE,
        "--client-command", shlex.join(crash) + " {url}", "--json", str(report),
    )  # fmt: skip
    assert done.returncode == 2, done.stderr
    (result,) = _results(report).values()
    assert result["verdict"] == "inconclusive"
    assert "ended before it connected" in str(result["reason"])
    assert "exited with status 3" in str(result["reason"])
    url = f"rctp://127.0.0.1:{port}/rctp/client/connect-first"
    exchange = result["exchange"]
    assert isinstance(exchange, list)
    assert any(f"cannot start for {url}" in str(entry["summary"]) for entry in exchange)


def test_without_a_client_the_first_case_waits_and_says_so_and_the_rest_give_up(
    tmp_path: Path,
) -> None:
    port = free_pair()
    report = tmp_path / "run.json"
    done = run_command(
        "run", "--role", "client", "--listen", str(port), *TWO_CASES,
        "--connect-timeout", "0.5", "--json", str(report),
    )  # fmt: skip
    assert done.returncode == 2, done.stderr
    assert "case 1 of 2: waiting for a client at rctp://127.0.0.1:" in done.stderr
    assert "case 2 of 2" not in done.stderr
    reasons = sorted(str(r["reason"]) for r in _results(report).values())
    assert reasons[0].startswith("no client connected for rctp://"), reasons
    assert reasons[1].startswith("no client has connected to the harness"), reasons


def test_a_local_system_started_per_case_runs_the_local_cases(tmp_path: Path) -> None:
    port = free_pair()
    report = tmp_path / "run.json"
    # The project's foreign local system (tests/foreign/), one run of D-RSP-24 per start.
    main, model = FOREIGN / "rsp_local" / "main.py", FOREIGN / "rsp_local" / "robot.rmodel"
    local = shlex.join([sys.executable, str(main), "--model", str(model)]) + " --robot {url}"
    done = run_command(
        "run", "--role", "local", "--listen", str(port), "--model", str(model),
        "--only", "rsp/local/downlink-header", "--only", "rsp/local/bye-ends",
        "--client-command", local, "--json", str(report),
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert f"sending to 127.0.0.1:{port}" in done.stderr
    assert {r["verdict"] for r in _results(report).values()} == {"pass"}


def test_without_a_local_system_the_first_case_waits_and_says_so_and_the_rest_give_up(
    tmp_path: Path,
) -> None:
    port = free_pair()
    report = tmp_path / "run.json"
    model = FOREIGN / "rsp_local" / "robot.rmodel"
    done = run_command(
        "run", "--role", "local", "--listen", str(port), "--model", str(model),
        "--only", "rsp/local/downlink-header", "--only", "rsp/local/bye-ends",
        "--connect-timeout", "0.5", "--json", str(report),
    )  # fmt: skip
    assert done.returncode == 2, done.stderr
    assert f"case 1 of 2: waiting for a HELLO at 127.0.0.1:{port}" in done.stderr
    assert "case 2 of 2" not in done.stderr
    reasons = sorted(str(r["reason"]) for r in _results(report).values())
    assert reasons[0].startswith("no local system has sent a HELLO"), reasons
    assert reasons[1].startswith("no local system sent a HELLO"), reasons


def test_a_command_without_its_url_or_role_is_a_usage_error() -> None:
    port = str(free_pair())
    no_url = run_command(
        "run", "--role", "client", "--listen", port, "--client-command", "my-client"
    )
    assert no_url.returncode == 2
    assert "{url}" in no_url.stderr
    no_role = run_command("run", "--client-command", "my-client {url}")
    assert no_role.returncode == 2
    assert "--role client and --role local" in no_role.stderr
