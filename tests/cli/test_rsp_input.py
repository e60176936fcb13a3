"""`rcmlconf robot` and `rcmlconf local` refuse bad input before any packet, and a session they
opened always ends with BYE: the robot is free for the next local system at once, not busy until
its 10 s timeout (D-RSP-12, R-RSP-22). Real processes on 127.0.0.1, as a user runs them."""

from __future__ import annotations

import re
import select
import signal
import socket
import subprocess
import threading
import time
from pathlib import Path

import pytest
from support.processes import BOUND, COMMAND, Running, run_command, running
from support.rsp_models import CUBO, robot_model

from rcmlconf.rsp.session.local import LocalEndpoint

MODEL = str(CUBO)
#: The simulacrum's usual run: the wheels turn, so the position changes every period.
DRIVE = ("--activate", "base", "--write", "leftWheel", "speed=200", "--watch", "position")
CAMERA = CUBO.parents[1] / "camera" / "camera.rcml"
HEX_SESSION = re.compile(r"session ([0-9a-f]{12}) ")


def _usage_error(done: subprocess.CompletedProcess[str], *words: str) -> None:
    """Exit 2, a usage line naming every one of `words`, and nothing of a bug."""
    assert done.returncode == 2, done.stderr
    last = done.stderr.strip().splitlines()[-1]
    for word in words:
        assert word in last, (word, done.stderr)
    assert "bug in rcmlconf" not in done.stderr


def _local(robot: dict[str, object], *args: str) -> subprocess.CompletedProcess[str]:
    return run_command("local", MODEL, "--robot", f"127.0.0.1:{robot['port']}", *args)


def _driving(robot: dict[str, object]) -> subprocess.Popen[str]:
    """`rcmlconf local` driving the robot until stopped, its output read as it comes."""
    return _started(robot["port"], *DRIVE)


def _started(port: object, *args: str) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [*COMMAND, "local", MODEL, "--robot", f"127.0.0.1:{port}", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def _free(robot: dict[str, object]) -> None:
    """The robot gives the next local system a session at once, which a busy one refuses."""
    done = _local(robot, "--duration", "0.1")
    assert done.returncode == 0, done.stderr
    assert HEX_SESSION.search(done.stderr), done.stderr


def _free_then_stop(robot: Running) -> str:
    """`_free`, then the robot stopped as a user stops it: its log."""
    _free(robot.ready)
    status, out, _ = robot.stop()
    assert status == 0
    return out


def test_a_ready_file_that_cannot_be_written_is_one_line() -> None:
    # robot wrote it unguarded (an internal error); serve and robot now share one writer.
    for command, *args in (("robot", MODEL), ("serve", str(CAMERA), "--no-http")):
        for path, why in (
            ("/nonexistent/d/r.json", "/nonexistent/d/r.json: cannot write it: No such file"),
            ("", "'.': not a file's name"),
        ):
            done = run_command(command, *args, "--port", "0", "--ready-file", path)
            assert done.returncode == 2, done.stderr
            assert f"rcmlconf {command}: --ready-file {why}" in done.stderr
            assert "bug in rcmlconf" not in done.stderr


def test_period_and_duration_refuse_nan_infinities_and_what_is_out_of_range() -> None:
    # --duration nan used to run for as long as the loop took NaN to be; --period nan was an
    # internal error.
    for option, values in (
        ("--period", ("nan", "inf", "-inf", "1e309", "0.004", "10.001")),
        ("--duration", ("nan", "inf", "1e309", "0", "-1", "86401")),
    ):
        for value in values:
            done = run_command("local", MODEL, "--robot", "127.0.0.1:9", option, value)
            _usage_error(done, f"'{option}'", value)


def test_a_bad_option_sends_nothing_and_the_robot_stays_free(tmp_path: Path) -> None:
    with running(tmp_path, "robot", "--port", "0", "-v", MODEL) as robot:
        for args, words in (
            (("--watch", "leftWheel"), ("'--watch'", "'leftWheel' is an effector", "position")),
            (("--activate", "leftWheel"), ("'--activate'", "takes a module", "base")),
            (("--write", "position", "x=1"), ("'--write'", "'position' is a sensor")),
            (("--issue", "lowBattery", "charge=1"), ("'--issue'", "is a memoryEvent")),
            (("--issue", "motion", "duration=5"), ("'--issue'", "no value for leftArm")),
            (("--write", "leftWheel", "speed=1", "--write", "leftWheel", "speed=2"), ("twice",)),
            (("--watch", "nothing"), ("'--watch'", "no device 'nothing'")),
        ):
            _usage_error(_local(robot.ready, *args), *words)
        out = _free_then_stop(robot)
    # No HELLO from the refused runs: the robot opened the one session it was asked for.
    assert out.count(" opened with ") == 1, out


def test_a_lost_output_after_the_session_opened_still_ends_it_with_bye(tmp_path: Path) -> None:
    with running(tmp_path, "robot", "--port", "0", "-v", MODEL) as robot:
        target = f"127.0.0.1:{robot.ready['port']}"
        # A full disk: the first value printed fails; the command says so and ends.
        with open("/dev/full", "w") as full:
            done = subprocess.run(
                [*COMMAND, "local", MODEL, "--robot", target, *DRIVE],
                stdout=full,
                stderr=subprocess.PIPE,
                text=True,
                timeout=BOUND,
                check=False,
            )
        assert done.returncode == 2, done.stderr
        assert "cannot write the output: No space left on device" in done.stderr
        assert "Traceback" not in done.stderr
        _free(robot.ready)
        # `| head -n 1`: the reader takes a line and goes; the command ends as it does, with 0.
        reader = _driving(robot.ready)
        assert reader.stdout is not None
        assert "position x=" in reader.stdout.readline()
        reader.stdout.close()
        assert reader.wait(timeout=BOUND) == 0
        assert reader.stderr is not None
        assert "Traceback" not in reader.stderr.read()
        out = _free_then_stop(robot)
    assert out.count("session ended by the local system: closed") == 4, out


def test_ctrl_c_ends_the_session_with_bye(tmp_path: Path) -> None:
    with running(tmp_path, "robot", "--port", "0", "-v", MODEL) as robot:
        local = _driving(robot.ready)
        assert local.stdout is not None
        local.stdout.readline()  # the session is open: a value came
        local.send_signal(signal.SIGINT)
        _, err = local.communicate(timeout=BOUND)
        assert local.returncode == 0, err
        out = _free_then_stop(robot)
    assert out.count("session ended by the local system: closed") == 2, out


def test_ctrl_c_while_hello_awaits_its_answer_still_ends_the_session(tmp_path: Path) -> None:
    # The robot opens a session at HELLO; a local system that quit before WELCOME came would
    # leave it busy for 10 s. A relay holds the HELLO until Ctrl-C was sent.
    with running(tmp_path, "robot", "--port", "0", "-v", MODEL) as robot:
        robot_address = ("127.0.0.1", int(str(robot.ready["port"])))
        with (
            socket.socket(type=socket.SOCK_DGRAM) as front,
            socket.socket(type=socket.SOCK_DGRAM) as back,
        ):
            front.bind(("127.0.0.1", 0))
            front.settimeout(BOUND)
            local = _started(front.getsockname()[1])
            hello, local_system = front.recvfrom(65535)
            local.send_signal(signal.SIGINT)
            # For the signal to be taken first (were it not, the test would show nothing).
            time.sleep(0.3)
            back.sendto(hello, robot_address)
            stop = threading.Event()
            relay = threading.Thread(
                target=_relay, args=(front, back, robot_address, local_system, stop)
            )
            relay.start()
            try:
                _, err = local.communicate(timeout=BOUND)
            finally:
                stop.set()
                relay.join(timeout=BOUND)
        assert local.returncode == 0, err
        assert HEX_SESSION.search(err), err
        out = _free_then_stop(robot)
    assert out.count("session ended by the local system: closed") == 2, out


def _relay(
    front: socket.socket,
    back: socket.socket,
    robot: tuple[str, int],
    local: tuple[str, int],
    stop: threading.Event,
) -> None:
    """Datagrams from the local system (to `front`) on to the robot, and the robot's back."""
    while not stop.is_set():
        ready, _, _ = select.select([front, back], [], [], 0.05)
        for sock in ready:
            data = sock.recv(65535)
            if sock is front:
                back.sendto(data, robot)
            else:
                front.sendto(data, local)


def test_robot_v_prints_readable_lines_and_the_session_id_local_prints(tmp_path: Path) -> None:
    with running(tmp_path, "robot", "--port", "0", "-vv", MODEL) as robot:
        done = _local(robot.ready, *DRIVE, "--issue", "irFire", "code=7", "--duration", "0.3")
        status, out, _ = robot.stop()
    assert done.returncode == 0, done.stderr
    assert status == 0
    found = HEX_SESSION.search(done.stderr)
    assert found is not None, done.stderr
    assert f"session {found.group(1)} opened with 127.0.0.1:" in out, out
    for line in ("irFire #0 <- code=7", "leftWheel <- speed=200", "ended by the local system"):
        assert line in out, (line, out)
    # No Python reprs: enums (`<ByeReason.CLOSED: 0>`), bytes, dicts, dataclasses.
    assert not re.search(r"<\w+\.\w+: |b'|\{'|\w+\(\w+=", out), out


def test_the_other_options_refuse_bad_input_in_one_line(tmp_path: Path) -> None:
    empty = tmp_path / "empty.key"
    empty.write_bytes(b"")
    crypto = ("--encryption", "aes-256-gcm", "--psk-file")
    local = ("local", MODEL, "--robot", "127.0.0.1:9")
    for args, words in (
        # An endless key file was read to the end of memory.
        ((*local, *crypto, "/dev/zero"), ("'--psk-file'", "/dev/zero", "longer than a key")),
        ((*local, *crypto, str(empty)), ("'--psk-file'", "64 hex digits")),
        ((*local, *crypto, "/nonexistent/k"), ("'--psk-file'", "cannot be read")),
        (("robot", MODEL, *crypto, "/dev/zero"), ("'--psk-file'", "/dev/zero")),
        (("robot", MODEL, "--encryption", "aes-256-gcm"), ("give --psk-file",)),
        # Python's resolver refused these with UnicodeError, not OSError: an internal error.
        (("local", MODEL, "--robot", "a..b"), ("'--robot'", "'a..b'")),
        (("robot", MODEL, "--host", "a..b"), ("'--host'", "'a..b'")),
        (("robot", MODEL, "--host", "a" * 64), ("'--host'",)),
        (("local", MODEL, "--robot", "[::1"), ("'--robot'", "'[::1'")),
        (("local", MODEL, "--robot", "h:" + "9" * 5000), ("'--robot'", "port")),
    ):
        _usage_error(run_command(*args), *words)


def test_the_article_follows_the_word() -> None:
    endpoint = LocalEndpoint(robot_model())
    with pytest.raises(TypeError, match=r"^position is a sensor: only an effector can be written$"):
        endpoint.write("position", {})
    with pytest.raises(TypeError, match=r"^base is a module: only a command or memoryCommand can"):
        endpoint.issue("base", {})
