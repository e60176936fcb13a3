"""What `rcmlconf run`'s exit status and lines tell a CI gate (issue 16: an error is an error, a
run that tested nothing is not green, --strict), as a user runs it: real processes."""

from __future__ import annotations

from pathlib import Path

from support.case_counts import MSG_CASES
from support.processes import free_port, run_command, running

from rcmlconf.conformance.registry import all_cases
from rcmlconf.conformance.targets import REFERENCE_RCML, REFERENCE_RMODEL


def test_a_run_in_which_no_case_passed_or_failed_is_not_green() -> None:
    """No client ever connects: every case is inconclusive, and the run says nothing was tested
    (before: 13 inconclusive, status 0)."""
    port = str(free_port())
    # A case waits --connect-timeout for its client (10 s by default): half a second will do.
    waits = ["--connect-timeout", "0.5"]
    done = run_command(
        "run", "--role", "client", "--listen", port, *waits, "--only", "rctp/client/conn*"
    )
    assert done.returncode == 2, done.stderr
    last = done.stderr.splitlines()[-1]
    assert last.startswith("rcmlconf run: no case passed or failed (1 inconclusive)"), last
    assert "nothing was tested" in last
    assert "no client connected" in last


def test_strict_makes_inconclusive_fail_the_run(tmp_path: Path) -> None:
    """The reference server as a target announces a 60 s session timeout, which the session
    cases do not wait for: inconclusive, which --strict counts as a failure."""
    with running(tmp_path, "serve", str(REFERENCE_RCML), "--port", "0", "--http-port", "0") as up:
        port = up.rctp_port
        target = ["--target", f"127.0.0.1:{port}", "--rcml", str(REFERENCE_RCML)]
        # Not slow-client-kept: it takes 8 s, and passes.
        chosen = ["--only", "rctp/session/*", "--skip", "rctp/session/slow-*"]
        lenient = run_command("run", *target, *chosen)
        strict = run_command("run", *target, *chosen, "--strict")
    assert "inconclusive" in lenient.stderr
    assert lenient.returncode == 0, lenient.stderr
    assert strict.returncode == 1, strict.stderr
    assert strict.stderr.splitlines()[-1].startswith("rcmlconf run: --strict: ")


def test_target_without_rcml_takes_the_robots_files(tmp_path: Path) -> None:
    """D-RCTP-29: the RCML the server's files list, as a client given only the URL finds it
    (before: CONNECT / got 404 and six cases failed)."""
    port = free_port()
    with running(tmp_path, "serve", str(REFERENCE_RCML), "--port", str(port)) as up:
        assert str(port) in str(up.ready["rctp"])
        done = run_command("run", "--target", f"127.0.0.1:{port}", "--only", "rctp/msg/*")
    assert done.returncode == 0, done.stderr
    assert "from its files (D-RCTP-29)" in done.stderr
    assert done.stderr.splitlines()[-1].endswith(f": {MSG_CASES} results: {MSG_CASES} pass")


def test_target_without_rcml_and_without_files_is_a_usage_error(tmp_path: Path) -> None:
    with running(tmp_path, "serve", str(REFERENCE_RCML), "--port", "0", "--no-http") as up:
        port = up.rctp_port
        done = run_command("run", "--target", f"127.0.0.1:{port}", "--only", "rctp/msg/*")
    assert done.returncode == 2
    (line,) = done.stderr.splitlines()
    assert "without --rcml" in line
    assert "D-RCTP-29" in line
    assert "give --rcml ROBOT.rcml" in line


def test_list_shows_the_cases_of_the_roles_the_options_test() -> None:
    local = ["--role", "local", "--listen", "7", "--model", str(REFERENCE_RMODEL)]
    listed = run_command("run", "--list", *local).stdout.splitlines()
    assert listed
    assert all(line.startswith("rsp/local/") for line in listed), listed
    servers = run_command("run", "--list", "--target", "127.0.0.1:9").stdout.splitlines()
    assert all(line.startswith("rctp/") and "(server)" in line for line in servers)


def test_the_cases_left_out_say_how_to_test_their_role(tmp_path: Path) -> None:
    with running(tmp_path, "robot", str(REFERENCE_RMODEL), "--port", "0") as robot:
        target = f"127.0.0.1:{robot.ready['port']}"
        done = run_command(
            "run", "--rsp-target", target, "--model", str(REFERENCE_RMODEL), "--only", "rsp/[lm]*"
        )
    local = sum(1 for case in all_cases() if case.startswith("rsp/local"))
    left = [line for line in done.stderr.splitlines() if line.startswith("left out")]
    assert left == [
        f"left out, as {target} does not play their role: {local} cases of an RSP local system:"
        " --role local --listen"
    ]


def test_session_wait_waits_out_a_longer_session_timeout(tmp_path: Path) -> None:
    """A server announcing 7 s: the session cases say how to wait for it, and with
    --session-wait 7 they do, and pass (the default waits 5 s)."""
    serve = ("serve", str(REFERENCE_RCML), "--port", "0", "--http-port", "0")
    with running(tmp_path, *serve, "--session-timeout", "7") as up:
        port = up.rctp_port
        target = ["--target", f"127.0.0.1:{port}", "--rcml", str(REFERENCE_RCML)]
        case = ["--only", "rctp/session/timeout-bye", "--json", str(tmp_path / "r.json")]
        short = run_command("run", *target, *case, "--verbose")
        waited = run_command("run", *target, *case, "--session-wait", "7")
    assert "--session-wait 7 waits for it" in short.stdout + short.stderr
    assert short.returncode == 2  # nothing passed or failed
    assert waited.returncode == 0, waited.stdout + waited.stderr
    assert waited.stderr.splitlines()[-1].endswith("1 results: 1 pass")
