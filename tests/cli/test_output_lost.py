"""Standard output that cannot be written: a full disk is one line and status 2, a reader that
went away (`rcmlconf dissect x.pcap | head`) is status 0, and neither is an internal error."""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest
from support.processes import BOUND, COMMAND

ROOT = Path(__file__).resolve().parents[2]
CAPTURE = str(ROOT / "captures" / "rctp-impaired.pcap")
COMMANDS = {
    "validate": ("validate", str(ROOT / "vectors" / "xml" / "invalid")),
    "dissect": ("dissect", CAPTURE),
    "wireshark": ("wireshark",),
    "cases": ("cases",),
}


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="needs /dev/full")
@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_a_full_disk_is_one_line_and_status_2(command: str) -> None:
    with open("/dev/full", "w") as full:
        done = subprocess.run(
            [*COMMAND, *COMMANDS[command]],
            stdout=full,
            stderr=subprocess.PIPE,
            text=True,
            timeout=BOUND,
            check=False,
        )
    assert done.returncode == 2, done.stderr
    said = [line for line in done.stderr.splitlines() if "cannot write" in line]
    assert said == ["rcmlconf: cannot write the output: No space left on device"], done.stderr
    assert "Traceback" not in done.stderr
    assert "bug in rcmlconf" not in done.stderr


#: Commands that write more than a pipe holds (64 KiB on Linux): the reader's going away is seen.
LONG = {"dissect -V": ("dissect", "-V", CAPTURE), "wireshark": ("wireshark",)}


@pytest.mark.parametrize("command", sorted(LONG))
def test_a_reader_that_goes_away_is_not_an_error(command: str) -> None:
    """As `| head -1`: the first line read, then the pipe closed while more was coming."""
    whole = subprocess.run(
        [*COMMAND, *LONG[command]], capture_output=True, timeout=BOUND, check=False
    )
    assert len(whole.stdout) > 1 << 16  # the test can fail: the writer must meet the closed pipe
    process = subprocess.Popen(
        [*COMMAND, *LONG[command]], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    assert process.stdout is not None
    assert process.stderr is not None
    assert process.stdout.readline()
    process.stdout.close()
    err = process.stderr.read()
    assert process.wait(BOUND) == 0, err  # click made it 1
    assert "Traceback" not in err
    assert "bug in rcmlconf" not in err
    assert "cannot write" not in err
