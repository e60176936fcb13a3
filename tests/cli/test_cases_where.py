"""`rcmlconf cases --where ID`: the file and line a case is written at, or a refusal that names
the IDs nearest to the one given. Real processes, as a user runs them."""

from __future__ import annotations

import json
from pathlib import Path

from support.processes import run_command

from rcmlconf.conformance.registry import all_cases


def where(case_id: str) -> tuple[Path, int]:
    done = run_command("cases", "--where", case_id)
    assert done.returncode == 0, done.stderr
    path, _, line = done.stdout.strip().rpartition(":")
    return Path(path), int(line)


def test_where_gives_the_line_of_the_case_in_the_module_of_its_area() -> None:
    path, line = where("rctp/msg/unknown-method")
    assert path.parts[-2:] == ("rctp_msg", "messages.py")
    lines = path.read_text().splitlines()
    assert lines[line - 1] == "@case("
    assert lines[line] == '    "rctp/msg/unknown-method",'


def test_where_of_a_case_a_loop_registers_gives_the_function_it_runs() -> None:
    found = all_cases()["rsp/security/aes-256-gcm-tampered"]
    path, line = where(found.id)
    assert path.name == "rsp_security.py"
    assert line == found.run.__code__.co_firstlineno


def test_where_in_json_names_the_id_path_and_line() -> None:
    done = run_command("cases", "--where", "rsp/header/layout", "--format", "json")
    assert done.returncode == 0, done.stderr
    shown = json.loads(done.stdout)
    assert shown["id"] == "rsp/header/layout"
    assert Path(shown["path"]).name == "rsp_header.py"
    assert isinstance(shown["line"], int)


def test_an_unknown_id_exits_2_naming_the_nearest() -> None:
    done = run_command("cases", "--where", "rsp/local/helo")
    assert done.returncode == 2, done.stderr
    assert done.stdout == ""
    assert "no case has the ID 'rsp/local/helo'; did you mean rsp/local/hello," in done.stderr
    # A bare name finds the cases of every area that have it.
    done = run_command("cases", "--where", "unknown-method")
    assert done.returncode == 2, done.stderr
    assert "rctp/client/unknown-method, rctp/msg/unknown-method" in done.stderr
    done = run_command("cases", "--where", "zzz")
    assert done.returncode == 2, done.stderr
    assert "(`rcmlconf cases` lists them)" in done.stderr


def test_where_takes_no_other_choice_of_cases() -> None:
    done = run_command("cases", "--where", "rsp/header/layout", "--only", "rsp/*")
    assert done.returncode == 2, done.stderr
    assert "--where takes no --matrix, --only or --strict" in done.stderr
