"""`rcmlconf validate` as a user runs it: the installed command, real files, exit statuses."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest
from support.processes import run_without_stdin
from support.report_schemas import assert_json_valid
from support.xml_vectors import XML_VECTORS

from rcmlconf.validate.report import SCHEMA as REPORT_SCHEMA

SCRIPT = Path(sys.executable).parent / "rcmlconf"
COMMAND = [str(SCRIPT)] if SCRIPT.exists() else [sys.executable, "-m", "rcmlconf"]
VALID = XML_VECTORS / "valid"
INVALID = XML_VECTORS / "invalid"
LINE = re.compile(r"^\S+:\d+:\d+: (error|warning): \[R-[A-Z]+-\d+\] .+$")


def run(
    *args: str, stdin: bytes | None = None, cwd: Path | None = None
) -> subprocess.CompletedProcess[str]:
    done = subprocess.run(
        [*COMMAND, *args],
        input=stdin.decode() if stdin else None,
        capture_output=True,
        text=True,
        timeout=60,
        cwd=cwd,
        check=False,
    )
    assert "Traceback" not in done.stderr, done.stderr
    if "json" in args and done.stdout:  # every report is what the schema shipped says
        assert_json_valid(json.loads(done.stdout), REPORT_SCHEMA)
    return done


def test_valid_files_exit_0_quietly() -> None:
    done = run("validate", str(VALID / "appendix-a-corrected.rcml"), str(VALID / "sample.rxid"))
    assert done.returncode == 0
    assert done.stdout == ""
    assert "2 files checked: all valid" in done.stderr


def test_the_paper_as_printed_exits_1_at_line_21_column_14() -> None:
    done = run("validate", str(INVALID / "appendix-a-as-printed.rcml"))
    assert done.returncode == 1
    assert done.stdout.strip() == (
        f"{INVALID / 'appendix-a-as-printed.rcml'}:21:14: error: [R-XML-1] attributes construct "
        "error (hint: missing whitespace between attributes)"
    )


def test_every_error_of_a_file_one_a_line() -> None:
    done = run("validate", str(INVALID / "rcml-types.rcml"))
    lines = done.stdout.splitlines()
    assert done.returncode == 1
    assert len(lines) == 12
    assert all(LINE.match(line) for line in lines), lines


def test_directories_are_searched_for_rcml_and_rxid_files() -> None:
    done = run("validate", "-q", "--format", "json", str(XML_VECTORS))
    report = json.loads(done.stdout)
    paths = {Path(f["path"]).name for f in report["files"]}
    assert "appendix-a-as-printed.rcml" in paths
    assert "testbot.rxid" in paths
    assert not any(p.endswith(".expected") for p in paths)
    assert done.returncode == 1
    assert done.stderr == ""


def test_json_holds_the_same_diagnostics() -> None:
    path = INVALID / "rxid-values.rxid"
    text = run("validate", str(path)).stdout.splitlines()
    report = json.loads(run("validate", "--format", "json", str(path)).stdout)
    assert report["version"] == 1
    assert report["summary"] == {"files": 1, "valid": 0, "invalid": 1, "errors": 6, "warnings": 0}
    assert set(report["diagnostics"][0]) == {
        "path",
        "line",
        "column",
        "severity",
        "rule",
        "message",
        "hint",
    }
    rebuilt = [
        f"{d['path']}:{d['line']}:{d['column']}: {d['severity']}: [{d['rule']}] {d['message']}"
        + (f" (hint: {d['hint']})" if d["hint"] else "")
        for d in report["diagnostics"]
    ]
    assert rebuilt == text


def test_standard_input() -> None:
    data = (INVALID / "rcml-version.rcml").read_bytes()
    done = run("validate", "-", stdin=data)
    assert done.returncode == 1
    assert done.stdout.startswith("<stdin>:2:7: error: [R-RCML-1]")


def test_binary_standard_input_is_one_invalid_document() -> None:
    done = subprocess.run(
        [*COMMAND, "validate", "-"],
        input=bytes(range(256)) * 64,
        capture_output=True,
        timeout=60,
        check=False,
    )
    assert done.returncode == 1
    assert done.stdout.decode().startswith("<stdin>:1:1: error: [R-XML-1]")
    assert done.stderr == b"1 file checked: 1 invalid (1 error)\n"


def test_closed_standard_input_cannot_be_read() -> None:
    done = run_without_stdin(*COMMAND, "validate", "-")
    assert done.returncode == 2
    assert done.stderr.splitlines() == [
        "error: cannot read -: standard input is closed",
        "0 files checked: all valid; 1 file could not be read",
    ]


@pytest.mark.parametrize(
    "args",
    [
        ["validate", "-", "-"],
        ["validate", "no-such-file.rcml"],
        ["validate", "--frobnicate", "x"],
        ["validate"],
        ["validate", "--format", "xml", str(VALID)],
        ["validate", "--map", "nothing", str(VALID)],
        ["no-such-command"],
    ],
)
def test_usage_errors_exit_2(args: list[str]) -> None:
    done = run(*args)
    assert done.returncode == 2
    assert done.stdout == ""
    assert "Error" in done.stderr


def test_a_directory_with_nothing_to_check_is_a_usage_error(tmp_path: Path) -> None:
    (tmp_path / "notes.txt").write_text("not a document")
    (tmp_path / "sub.rcml").mkdir()  # a directory, whatever its name
    done = run("validate", str(tmp_path))
    assert done.returncode == 2
    assert done.stdout == ""
    assert done.stderr.splitlines()[-1] == (
        "Error: Invalid value for 'PATH...': nothing to check: no *.rcml, *.rmodel or *.rxid"
        f" file below '{tmp_path}' (--allow-empty accepts that)"
    )
    assert "0 files checked" not in done.stderr


def test_allow_empty_accepts_nothing_to_check(tmp_path: Path) -> None:
    done = run("validate", "--allow-empty", str(tmp_path))
    assert done.returncode == 0
    assert done.stderr == "0 files checked: all valid\n"
    report = json.loads(run("validate", "--allow-empty", "--format", "json", str(tmp_path)).stdout)
    assert report["summary"]["files"] == 0


def test_a_weird_name_is_shown_on_one_line(tmp_path: Path) -> None:
    weird = tmp_path / "new\nline"
    weird.mkdir()
    done = run("validate", str(weird))
    assert done.returncode == 2
    assert done.stderr.splitlines()[-1].endswith(
        f"file below '{tmp_path}/new\\nline' (--allow-empty accepts that)"
    )


@pytest.mark.skipif(not Path("/proc/self/mem").exists(), reason="needs Linux /proc")
def test_unreadable_files_exit_2_and_the_others_are_still_checked() -> None:
    # Reading /proc/self/mem at offset 0 fails with EIO, for root too.
    done = run("validate", "/proc/self/mem", str(INVALID / "rcml-version.rcml"))
    assert done.returncode == 2
    assert "error: cannot read /proc/self/mem" in done.stderr
    assert "[R-RCML-1]" in done.stdout


@pytest.mark.skipif(not Path("/proc/self/mem").exists(), reason="needs Linux /proc")
def test_an_unreadable_file_with_a_weird_name_is_one_line(tmp_path: Path) -> None:
    weird = tmp_path / "new\nline.rcml"
    weird.symlink_to("/proc/self/mem")
    done = run("validate", str(weird))
    assert done.returncode == 2
    assert done.stderr.splitlines()[0] == (
        f"error: cannot read {tmp_path}/new\\nline.rcml: Input/output error"
    )


def test_warnings_pass_unless_strict() -> None:
    path = str(VALID / "empty-access.rcml")
    assert run("validate", path).returncode == 0
    assert run("validate", "--strict", path).returncode == 1


def test_map_lets_a_url_session_be_checked() -> None:
    path = str(VALID / "unresolved-session.rxid")
    mapped = run(
        "validate",
        "--map",
        f"http://robot.example/camera.rcml={VALID / 'appendix-a-corrected.rcml'}",
        path,
    )
    assert mapped.returncode == 0
    assert mapped.stdout == ""
    assert "R-RXID-10" in run("validate", path).stdout


def test_help_teaches() -> None:
    done = run("validate", "--help")
    for words in ("RULE-ID", "--map", "Exit status", "never fetched", "Examples", "--allow-empty"):
        assert words in done.stdout
    # Every language's files are searched in a directory, and the help says which.
    assert "*.rcml, *.rxid and *.rmodel" in " ".join(done.stdout.split())
    top = run("--help")
    assert "validate" in top.stdout
    assert top.returncode == 0


def test_the_bundled_robots_are_valid_without_a_warning() -> None:
    done = run("validate", "--strict", "rcmlconf/reference/robots", cwd=Path(__file__).parents[2])
    assert done.returncode == 0, done.stdout
    assert "5 files checked: all valid" in done.stderr


def test_a_hostile_file_is_cut_short_and_says_so(tmp_path: Path) -> None:
    body = "".join(f'<dta name="d{i}"/>' for i in range(1500))
    path = tmp_path / "hostile.rcml"
    path.write_text(f'<rcml version="2.0" site="rctp://r"><access name="a">{body}</access></rcml>')
    cut = run("validate", str(path))
    assert cut.returncode == 1
    assert len(cut.stdout.splitlines()) == 1000
    assert "checking stopped at the limit of findings in 1 file" in cut.stderr
    report = json.loads(run("validate", "--format", "json", str(path)).stdout)
    assert report["files"][0]["truncated"] is True
    everything = run("validate", "--max-findings", "0", str(path))
    # 1,500 unknown elements, and the access holds no data node (R-RCML-24, a warning)
    assert len(everything.stdout.splitlines()) == 1501
