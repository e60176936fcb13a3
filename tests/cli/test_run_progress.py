"""`rcmlconf run`'s progress in a CI log (standard error no terminal): a line every 25 results,
and none of them on a terminal, where the live bar is (issue 19, item 7)."""

from __future__ import annotations

import os
import pty
import re
import subprocess

from support.case_counts import MSG_CASES
from support.processes import BOUND, COMMAND, run_command

QUICK = ("run", "--only", "rctp/msg/*", "--fault", "no-cseq-echo")
PROGRESS = re.compile(rf"\d+/{MSG_CASES} cases, \d+ fail(, \d+ error)? \(\d+ s\)")


def test_a_log_gets_a_line_every_25_cases_with_the_failures_so_far() -> None:
    done = run_command(*QUICK)
    assert done.returncode == 1, done.stderr
    lines = [line for line in done.stderr.splitlines() if f"/{MSG_CASES} cases" in line]
    assert all(PROGRESS.fullmatch(line) for line in lines), lines
    # Every 5 s without a line makes one more, so a slow machine may show others too.
    assert any(line.startswith(f"25/{MSG_CASES} cases, ") for line in lines), lines
    assert not any("cases, " in line for line in done.stdout.splitlines())


def test_a_terminal_gets_the_bar_not_the_lines() -> None:
    leader, follower = pty.openpty()
    try:
        process = subprocess.Popen(
            [*COMMAND, *QUICK], stdout=subprocess.DEVNULL, stderr=follower, text=True
        )
        os.close(follower)
        process.wait(timeout=BOUND * 3)
        shown = b""
        while True:
            try:
                chunk = os.read(leader, 65536)
            except OSError:  # EIO: the terminal's other side is closed and read to its end
                break
            if not chunk:
                break
            shown += chunk
    finally:
        os.close(leader)
    text = shown.decode(errors="replace")
    assert f"{MSG_CASES} results" in text  # the summary came through the terminal
    assert "cases, " not in text
