"""`rcmlconf run` and `rcmlconf cases` refuse bad input in one line naming it, with status 2, before
any case runs (issue 15). Real processes, real files and sockets on 127.0.0.1, as a user runs them.
"""

from __future__ import annotations

import os
import socket
import subprocess
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest
from support.processes import BOUND, COMMAND, free_port, run_command, running

from rcmlconf.cli.cases import cases
from rcmlconf.cli.run import run
from rcmlconf.conformance.targets import REFERENCE_RCML

ROOT = Path(__file__).resolve().parents[2]
ROVER = str(ROOT / "rcmlconf/reference/robots/rover/rover.rcml")
CUBO = str(ROOT / "rcmlconf/reference/robots/cubo/cubo.rmodel")
#: One quick case of the embedded reference, for the runs that must go on.
QUICK = ("--only", "rctp/msg/connect")
#: What a refusal may start with: click's usage error, or the command's own line.
STARTS = ("Error: ", "rcmlconf run: ", "rcmlconf cases: ")


def refusal(done: subprocess.CompletedProcess[str], *names: str) -> str:
    """The one line that refuses the input, which names each of `names`; status 2, no case run."""
    assert done.returncode == 2, (done.returncode, done.stderr)
    assert "Traceback" not in done.stderr, done.stderr
    assert "bug in rcmlconf" not in done.stderr, done.stderr
    lines = [line for line in done.stderr.splitlines() if line.startswith(STARTS)]
    assert len(lines) == 1, done.stderr
    for name in names:
        assert name in lines[0], (name, lines[0])
    assert "results:" not in done.stderr, "cases ran before the input was refused"
    return lines[0]


def refused_all(rows: Sequence[tuple[tuple[str, ...], tuple[str, ...]]]) -> None:
    """Each (args, names) row as its own process, a few at once (each takes a third of a second)."""

    def one(row: tuple[tuple[str, ...], tuple[str, ...]]) -> str:
        args, names = row
        done = subprocess.run(
            [*COMMAND, *args], capture_output=True, text=True, timeout=BOUND, check=False
        )
        try:
            refusal(done, *names)
        except AssertionError as error:
            return f"{args}: {error}"
        return ""

    with ThreadPoolExecutor(4) as pool:
        wrong = [found for found in pool.map(one, rows) if found]
    assert not wrong, "\n".join(wrong)


# -- 1. --ics ------------------------------------------------------------------------------------


def written(
    folder: Path, option: str, files: Sequence[tuple[str, str, tuple[str, ...]]]
) -> list[tuple[tuple[str, ...], tuple[str, ...]]]:
    """Each (name, text, words) a file in `folder`, and the row giving it to `option`."""
    rows = []
    for name, text, words in files:
        (folder / name).write_text(text)
        rows.append((("run", option, str(folder / name)), (option, name, *words)))
    return rows


def test_an_ics_that_is_not_one_is_refused_with_its_file_key_and_line(tmp_path: Path) -> None:
    files = [
        ("rsp5.toml", "rsp = 5\n", ("rsp5.toml:1:", "rsp must be a table")),
        ("files.toml", "[features]\nfiles = 1\n", ("files.toml:2:", "files must be true or false")),
        ("psk.toml", "[rsp]\npsk-file = 3\n", ("psk.toml:2:", "psk-file must be a file name")),
        ("typo.toml", "[features]\nfile = false\n", ("typo.toml:2:", "unknown feature file")),
        ("key.toml", "[rsp]\npsk = 'k'\n", ("key.toml:2:", "unknown key psk")),
        ("top.toml", "\nfeatures = {}\nextra = 1\n", ("top.toml:3:", "unknown table or key extra")),
        ("garbage.toml", "a = [\n", ("garbage.toml", "not TOML")),
        ("binary.toml", "", ("binary.toml", "not UTF-8 text")),
        ("nokey.toml", '[rsp]\npsk-file = "none.key"\n', ("nokey.toml:2:", "none.key")),
    ]
    rows = written(tmp_path, "--ics", files)
    (tmp_path / "binary.toml").write_bytes(bytes(range(128, 256)))
    missing = str(tmp_path / "missing.toml")
    rows.append((("run", "--ics", missing), ("--ics", "missing.toml")))
    rows.append((("run", "--ics", "/dev/zero"), ("--ics", "/dev/zero", "larger than an ICS")))
    refused_all(rows)


def test_an_ics_as_documented_is_taken(tmp_path: Path) -> None:
    ics = tmp_path / "ics.toml"
    ics.write_text("# a comment\n[features]\nfiles = false\n\n[rsp]\n")
    done = run_command("run", *QUICK, "--ics", str(ics))
    assert done.returncode == 0, done.stderr


# -- 2. --baseline -------------------------------------------------------------------------------


def test_a_baseline_that_is_not_one_is_refused(tmp_path: Path) -> None:
    files = [
        ("string.json", '{"results": "x"}', ("not a report of `rcmlconf run --json`",)),
        ("items.json", '{"results": [5, null]}', ("results[0] is not a result",)),
        ("list.json", "[1, 2, 3]", ("not a report",)),
        ("null.txt", "null", ("not a report",)),
        ("ids.json", '{"results": [{"id": 5}]}', ("results[0] is not a result",)),
        ("verdict.json", '{"results": [{"case": "rctp/a/b", "verdict": 1}]}', ("results[0]",)),
        ("garbage.json", '{"results": ', ("not a report",)),
        ("words.txt", "rctp/msg/connect\nsome words\n", ("words.txt:2:", "is not a case ID")),
    ]
    rows = written(tmp_path, "--baseline", files)
    rows.append((("run", "--baseline", "/dev/zero"), ("--baseline", "larger than a baseline")))
    refused_all(rows)


def test_baseline_ids_that_name_no_case_are_a_warning_and_the_run_goes_on(tmp_path: Path) -> None:
    known = tmp_path / "known.txt"
    known.write_text("rctp/msg/connect  # known\nrctp/gone/renamed\nrsp/x/y\n")
    done = run_command("run", *QUICK, "--baseline", str(known))
    assert done.returncode == 0, done.stderr
    warnings = [line for line in done.stderr.splitlines() if "warning" in line]
    assert warnings == [
        f"rcmlconf run: warning: {known} names 2 IDs that are no case: rctp/gone/renamed, rsp/x/y"
    ]
    assert "1 pass" in done.stderr


def test_a_report_of_an_earlier_run_is_a_baseline(tmp_path: Path) -> None:
    report = tmp_path / "r.json"
    first = run_command("run", *QUICK, "--json", str(report))
    assert first.returncode == 0, first.stderr
    again = run_command("run", *QUICK, "--baseline", str(report))
    assert again.returncode == 0, again.stderr
    assert "warning" not in again.stderr


# -- 3, 4, 11. numbers ---------------------------------------------------------------------------


def test_numbers_out_of_range_are_refused_before_any_case() -> None:
    rows: list[tuple[tuple[str, ...], tuple[str, ...]]] = [
        (("run", "--timeout-scale", value), ("--timeout-scale",))
        for value in ("nan", "inf", "1e309", "-1", "0.05", "101")
    ]
    rows += [(("run", "--repeat", value), ("--repeat",)) for value in ("0", "1001", "9" * 5000)]
    rows += [
        (("run", "--impair", spec), ("--impair", *words))
        for spec, words in [
            ("delay=1e9ms", ("delay=1e9ms", "0 to 10 s")),
            ("jitter=10.5s", ("jitter=10.5s", "0 to 10 s")),
            ("gap=20000ms,reorder=1%", ("gap=20000ms",)),
            ("burst=5000,loss=1%", ("burst=5000", "at most 1,000")),
            ("loss=nan%", ("nan",)),
            ("delay=1e400s", ("too large",)),
        ]
    ]
    refused_all(rows)


def test_the_help_documents_the_ranges() -> None:
    done = run_command("run", "--help")
    text = " ".join(done.stdout.split())
    assert "0.1<=x<=100" in text
    assert "delay, jitter, gap (0 to 10s" in text
    assert "burst (the mean run of losses, 1 to 1000)" in text


def test_a_negative_seed_is_a_seed_of_its_own() -> None:
    # Seeds are text to the impairment's hash: -1 and 1 make different runs, neither an error.
    done = run_command("run", *QUICK, "--seed", "-1")
    assert done.returncode == 0, done.stderr


# -- 5. addresses --------------------------------------------------------------------------------


def test_hosts_that_are_neither_addresses_nor_names_are_refused() -> None:
    rows: list[tuple[tuple[str, ...], tuple[str, ...]]] = []
    for value in ("::::", "", "a b", "a..b", "-a.example", "999.1.1.1", "[::1", "[1.2.3.4]"):
        rows.append((("run", "--target", value), ("--target", f"'{value}'")))
    for value in ("127.0.0.1:99999", "127.0.0.1:x", "127.0.0.1:", "[::1]:0"):
        rows.append((("run", "--target", value), ("--target", "port")))
    for value in ("::::", "127.0.0.1:x"):
        rows.append((("run", "--rsp-target", value, "--model", CUBO), ("--rsp-target", value)))
    for value in ("::::", "x", "-1", "70000", "a b:7330", "127.0.0.1"):
        rows.append((("run", "--role", "client", "--listen", value), ("--listen", f"'{value}'")))
    refused_all(rows)


def test_an_ipv6_target_in_brackets_is_taken() -> None:
    done = run_command("run", "--target", "[::1]:7330", "--list", *QUICK)
    assert done.returncode == 0, done.stderr
    assert "rctp/msg/connect" in done.stdout


def test_a_model_without_a_robot_to_describe_is_refused() -> None:
    # It was ignored: the embedded reference ran, and the user thought their model was used.
    refusal(run_command("run", "--model", CUBO, *QUICK), "--model describes --rsp-target")


def test_a_site_path_that_is_not_one_is_refused() -> None:
    refused_all(
        [
            (("run", "--target", "127.0.0.1:9", "--site", site), ("--site", "not a site path"))
            for site in ("rover", "/a b", "/x?y", "/\x01")
        ]
    )


# -- 6. a target that is not there --------------------------------------------------------------


def test_a_closed_port_is_one_line_naming_the_port_given() -> None:
    port = free_port(socket.SOCK_STREAM)
    done = run_command("run", "--target", f"127.0.0.1:{port}")
    line = refusal(done, f"--target 127.0.0.1:{port} (RCTP over TCP)", "connection refused")
    assert line.endswith("is the target running, on that port?")
    assert f"127.0.0.1:{port + 1}" not in done.stderr
    assert done.stdout == ""


def test_a_robot_port_nothing_listens_on_is_one_line_not_failures() -> None:
    # Before: 5 cases failed R-RSP-20/21 (no answer to HELLO) and 50 were inconclusive, in 96 s.
    port = free_port(socket.SOCK_DGRAM)
    done = run_command("run", "--rsp-target", f"127.0.0.1:{port}", "--model", CUBO)
    refusal(done, f"--rsp-target 127.0.0.1:{port} (RSP over UDP)", "nothing listens there")
    assert done.stdout == ""


def test_a_name_that_cannot_be_looked_up_is_one_line() -> None:
    done = run_command("run", "--target", "nowhere.invalid")  # RFC 6761: never resolves
    refusal(done, "--target nowhere.invalid:7330", "cannot look nowhere.invalid up")


def test_a_robot_that_is_there_is_tested(tmp_path: Path) -> None:
    with running(tmp_path, "robot", CUBO, "--port", "0") as robot:
        address = f"127.0.0.1:{robot.ready['port']}"
        done = run_command(
            "run", "--rsp-target", address, "--model", CUBO, "--only", "rsp/session/welcome"
        )
    assert done.returncode == 0, done.stderr
    assert "1 pass" in done.stderr


def test_a_target_that_is_there_is_tested() -> None:
    with socket.socket() as listening:
        listening.bind(("127.0.0.1", 0))
        listening.listen()
        port = listening.getsockname()[1]
        # It takes the connection and never answers: the case errs or fails on its own, but the
        # run gets past the first connection and reports on the case.
        done = run_command(
            "run", "--target", f"127.0.0.1:{port}", "--rcml", str(REFERENCE_RCML),
            "--only", "rctp/msg/connect", "--timeout-scale", "0.2", "--verbose",
        )  # fmt: skip
    assert "cannot reach --target" not in done.stderr
    assert "rctp/msg/connect" in done.stdout


# -- 7. report files that cannot be written ------------------------------------------------------


def test_reports_that_cannot_be_written_are_refused_before_any_case(tmp_path: Path) -> None:
    a_file = tmp_path / "file"
    a_file.write_text("")
    nowhere = tmp_path / "nowhere"
    rows: list[tuple[tuple[str, ...], tuple[str, ...]]] = []
    for option, name in (("--junit", "r.xml"), ("--json", "r.json")):
        rows.append((("run", option, str(nowhere / name)), (option, "nowhere does not exist")))
        rows.append((("run", option, str(a_file / name)), (option, "is not a directory")))
        rows.append((("run", option, str(tmp_path)), (option, "is a directory")))
    rows.append((("run", "--capture", str(a_file / "d")), ("--capture", "is not a directory")))
    rows.append((("run", "--capture", str(a_file)), ("--capture", "is a file")))
    same = str(tmp_path / "same")
    rows.append((("run", "--junit", same, "--json", same), ("--junit and --json",)))
    refused_all(rows)
    assert not nowhere.exists()


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes where permissions say no")
def test_a_directory_without_write_permission_is_refused(tmp_path: Path) -> None:
    locked = tmp_path / "locked"
    locked.mkdir(mode=0o500)
    refusal(run_command("run", "--junit", str(locked / "r.xml")), "--junit", "takes no new")
    refusal(run_command("run", "--capture", str(locked / "d")), "--capture", "takes no new")


def test_a_capture_directory_that_can_be_made_is_made(tmp_path: Path) -> None:
    captures = tmp_path / "deep" / "er"
    done = run_command("run", *QUICK, "--capture", str(captures))
    assert done.returncode == 0, done.stderr
    assert [p.name for p in captures.iterdir()] == ["rctp_msg_connect.pcap"]


# -- 8. globs ------------------------------------------------------------------------------------


def test_cases_and_run_refuse_the_same_globs_alike() -> None:
    rows: list[tuple[tuple[str, ...], tuple[str, ...]]] = []
    for command in ("cases", "run"):
        rows.append(((command, "--only", "["), ("--only", "'['", "no ] closes")))
        rows.append(((command, "--only", "rctp/[!msg/*"), ("--only", "no ] closes")))
        rows.append(((command, "--only", "nothing/*"), ("no case matches --only 'nothing/*'",)))
        rows.append(((command, "--only", ""), ("no case matches --only ''",)))
    rows.append((("run", "--skip", "rctp/[x"), ("--skip", "no ] closes")))
    rows.append((("run", "--skip", "*"), ("no case matches --skip '*'",)))
    refused_all(rows)


def test_globs_with_sets_still_choose() -> None:
    done = run_command("cases", "--only", "rctp/ms[g]/connect", "--only", "rctp/msg/[!x]are-lf")
    assert done.returncode == 0, done.stderr
    assert [line.split()[0] for line in done.stdout.splitlines()] == [
        "rctp/msg/bare-lf",
        "rctp/msg/connect",
    ]


# -- 9. help -------------------------------------------------------------------------------------


@pytest.mark.parametrize("command", ["run", "cases"])
@pytest.mark.parametrize("columns", ["80", "100"])
def test_help_breaks_no_word_across_lines(command: str, columns: str) -> None:
    done = subprocess.run(
        [*COMMAND, command, "--help"],
        capture_output=True,
        text=True,
        timeout=BOUND,
        check=False,
        env={**os.environ, "COLUMNS": columns},
    )
    assert done.returncode == 0, done.stderr
    shown = set(done.stdout.split())
    found = {"run": run, "cases": cases}[command]
    texts = [found.help or ""] + [getattr(p, "help", None) or "" for p in found.params]
    words = {word for text in texts for word in text.split() if word != "\b"}
    assert words - shown == set()  # "delay=4" and "0ms" on two lines lose "delay=40ms"
    assert max(len(line) for line in done.stdout.splitlines()) <= 80


# -- 11. the robot's files -----------------------------------------------------------------------


def test_robot_files_that_are_not_one_are_refused_naming_the_option(tmp_path: Path) -> None:
    empty = tmp_path / "empty.rcml"
    empty.write_bytes(b"")
    binary = tmp_path / "binary.rcml"
    binary.write_bytes(bytes(range(256)) * 64)
    huge = tmp_path / "huge.rcml"
    huge.write_bytes(b"<" * (17 * 1024 * 1024))
    odd = tmp_path / "new\nline.rcml"
    odd.write_bytes(b"\0")
    rows: list[tuple[tuple[str, ...], tuple[str, ...]]] = []
    for path, words in (
        (empty, ("empty.rcml", "R-XML-1")),
        (binary, ("binary.rcml",)),
        (huge, ("huge.rcml",)),
        (odd, ("new\\nline.rcml",)),
        (tmp_path, ("is a directory",)),
        (tmp_path / "missing", ("does not exist",)),
    ):
        rows.append((("run", "--target", "127.0.0.1:9", "--rcml", str(path)), ("--rcml", *words)))
        rows.append(
            (("run", "--rsp-target", "127.0.0.1:9", "--model", str(path)), ("--model", *words))
        )
    rows.append((("run", "--target", "127.0.0.1:9", "--rcml", CUBO), ("--rcml", "cubo.rmodel")))
    refused_all(rows)
