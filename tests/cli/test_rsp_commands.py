"""`rcmlconf robot` and `rcmlconf local` as a user runs them: real processes on 127.0.0.1."""

from __future__ import annotations

import json
import signal
from pathlib import Path

from support.processes import run_command, running
from support.rsp_models import EVERY_KIND

INVALID_MODEL = Path(__file__).parents[2] / "vectors" / "xml" / "invalid" / "rmodel-monitors.rmodel"
KEY = "00112233445566778899aabbccddeeff00112233445566778899aabbccddeeff"


def test_local_drives_the_robot_and_prints_what_changes(tmp_path: Path) -> None:
    with running(tmp_path, "robot", "--port", "0", "-v", str(EVERY_KIND)) as robot:
        target = f"127.0.0.1:{robot.ready['port']}"
        done = run_command(
            "local", str(EVERY_KIND), "--robot", target, "--format", "json",
            "--write", "arm", "shoulder=10", "--write", "arm", "elbow=20",
            "--write", "arm", "grip=true", "--watch", "armActual",
            "--issue", "beep", "tone=440", "--duration", "0.5",
        )  # fmt: skip
        status, out, _ = robot.stop(signal.SIGINT)
    assert done.returncode == 0, done.stderr
    lines = [json.loads(line) for line in done.stdout.splitlines()]
    assert lines[-1]["values"] == {"shoulder": 10, "elbow": 20, "grip": True}
    assert all(line["device"] == "armActual" for line in lines)
    assert "1 occurrence acknowledged" in done.stderr
    assert status == 0
    assert "beep #0 <- tone=440" in out
    assert "session ended by the local system: closed" in out


def test_an_encrypted_session_needs_the_same_key(tmp_path: Path) -> None:
    key = tmp_path / "robot.key"
    key.write_text(KEY + "\n")
    other = tmp_path / "other.key"
    other.write_bytes(bytes(32))
    args = ["--encryption", "aes-256-gcm"]
    with running(
        tmp_path, "robot", "--port", "0", *args, "--psk-file", str(key), str(EVERY_KIND)
    ) as robot:
        target = f"127.0.0.1:{robot.ready['port']}"
        good = run_command(
            "local",
            str(EVERY_KIND),
            "--robot",
            target,
            *args,
            "--psk-file",
            str(key),
            "--duration",
            "0.2",
        )
        bad = run_command(
            "local",
            str(EVERY_KIND),
            "--robot",
            target,
            *args,
            "--psk-file",
            str(other),
            "--duration",
            "0.2",
        )
        clear = run_command("local", str(EVERY_KIND), "--robot", target, "--duration", "0.2")
        robot.stop()
    assert good.returncode == 0, good.stderr
    assert bad.returncode == 1
    assert "refused: not authenticated" in bad.stderr
    assert "refused: encryption not offered" in clear.stderr


def test_usage_errors_exit_2_with_one_clear_line() -> None:
    model = str(EVERY_KIND)
    for args, words in (
        (["--write", "arm", "knee=1"], "a field of arm (shoulder, elbow, grip)"),
        (["--write", "arm", "shoulder=1000"], "shoulder"),
        (["--watch", "nothing"], "has no device 'nothing'"),
        (["--encryption", "aes-256-gcm"], "give --psk-file"),
    ):
        done = run_command("local", model, "--robot", "127.0.0.1:9", *args)
        assert done.returncode == 2, (args, done.stderr)
        assert words in done.stderr


def test_an_invalid_model_exits_1_with_its_diagnostics() -> None:
    for command in (["robot"], ["local", "--robot", "127.0.0.1"]):
        done = run_command(*command, str(INVALID_MODEL))
        assert done.returncode == 1
        assert "[R-RSP-9]" in done.stdout


def test_no_robot_exits_1() -> None:
    done = run_command("local", str(EVERY_KIND), "--robot", "127.0.0.1:9", "--duration", "0.1")
    assert done.returncode == 1
    assert "no answer to HELLO" in done.stderr


def test_a_port_in_use_exits_2(tmp_path: Path) -> None:
    with running(tmp_path, "robot", "--port", "0", str(EVERY_KIND)) as robot:
        done = run_command("robot", "--port", str(robot.ready["port"]), str(EVERY_KIND))
        robot.stop()
    assert done.returncode == 2
    assert "cannot listen on 127.0.0.1 UDP port" in done.stderr


def test_a_document_of_another_language_is_refused_in_one_line() -> None:
    rcml = (
        Path(__file__).parents[2] / "rcmlconf" / "reference" / "robots" / "camera" / "camera.rcml"
    )
    done = run_command("robot", str(rcml))
    assert done.returncode == 1
    assert "is a valid <rcml> document, not the one this command takes" in done.stderr
    assert "all valid" not in done.stderr
