"""The process monitor of `fuzz --target-command`: real targets, small Python programs.

Each program is written to the test's folder and run with this Python. Every wait is bounded.
"""

from __future__ import annotations

import os
import shlex
import signal
import socket
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

import pytest
from hypothesis import given
from hypothesis import strategies as st
from support.processes import free_port, lasting_port

from rcmlconf.fuzz.monitor import (
    Exit,
    LeakWatch,
    TargetCommandError,
    TargetNotReady,
    TargetProcess,
    Usage,
    _tree_by_parents,
    process_tree,
)

#: Every wait of these tests is bounded by this many seconds.
BOUND = 10.0
MiB = 2**20
T = TypeVar("T")

SERVE_TCP = """
import socket, sys, time
time.sleep(0.2)  # start() waits for the listener, not for the process
server = socket.create_server(("127.0.0.1", int(sys.argv[1])))
sys.stderr.write("listening\\n")
sys.stderr.flush()
while True:
    conn, _ = server.accept()
    with conn:
        try:
            conn.sendall(b"hello\\n")
        except OSError:
            pass
"""

SERVE_UDP = """
import socket, sys, time
time.sleep(0.2)
server = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
server.bind(("127.0.0.1", int(sys.argv[1])))
while True:
    data, peer = server.recvfrom(2048)
    server.sendto(data, peer)
"""

# Killed by SIGSEGV when a connection sends "crash".
CRASH_ON_ASK = """
import os, signal, socket, sys
server = socket.create_server(("127.0.0.1", int(sys.argv[1])))
while True:
    conn, _ = server.accept()
    with conn:
        if conn.recv(16).startswith(b"crash"):
            sys.stderr.write("crashing now\\n")
            sys.stderr.flush()
            os.kill(os.getpid(), signal.SIGSEGV)
"""

# Keeps each connection that asks, and 2 MiB of memory with it.
LEAKY = """
import socket, sys
server = socket.create_server(("127.0.0.1", int(sys.argv[1])))
kept = []
while True:
    conn, _ = server.accept()
    if not conn.recv(16):  # start()'s probe: no leak
        conn.close()
        continue
    kept.append((conn, bytes(range(256)) * (2 * 4096)))
    conn.sendall(b"ok\\n")
"""

# Allocates 30 MiB at the first connection that asks, then nothing more.
ONCE = """
import socket, sys
server = socket.create_server(("127.0.0.1", int(sys.argv[1])))
held = None
while True:
    conn, _ = server.accept()
    with conn:
        if conn.recv(16):
            if held is None:
                held = bytes(range(256)) * (30 * 4096)
            conn.sendall(b"ok\\n")
"""

# A child holds 20 MiB; the parent listens once the child holds it.
WITH_CHILD = """
import socket, subprocess, sys
CHILD = (
    "import time; held = bytes(range(256)) * (20 * 4096); print('held', flush=True);"
    " time.sleep(60)"
)
child = subprocess.Popen([sys.executable, "-c", CHILD], stdout=subprocess.PIPE)
child.stdout.readline()
server = socket.create_server(("127.0.0.1", int(sys.argv[1])))
while True:
    conn, _ = server.accept()
    conn.close()
"""

EXIT_3 = """
import sys
sys.stderr.write("bad config: no such site\\n")
sys.exit(3)
"""

NEVER_READY = """
import sys, time
sys.stderr.write("warming up\\n")
sys.stderr.flush()
time.sleep(30)
"""

NOISY = """
import sys
for number in range(5000):
    sys.stderr.write(f"line {number}\\n")
sys.exit(1)
"""


def command(tmp_path: Path, source: str, *args: object) -> str:
    """The command line that runs `source` with this Python, ARGS after it."""
    program = tmp_path / f"target_{len(list(tmp_path.glob('target_*.py')))}.py"
    program.write_text(source)
    return shlex.join([sys.executable, str(program), *map(str, args)])


def until(look: Callable[[], T | None], within: float = BOUND) -> T:
    """What `look` gives once it gives something, within `within` seconds."""
    deadline = time.monotonic() + within
    while (found := look()) is None:
        assert time.monotonic() < deadline, "waited too long"
        time.sleep(0.02)
    return found


def ask(port: int, what: bytes = b"hi") -> bytes:
    """Send `what` on a new connection; the answer, up to its end."""
    answer = b""
    with socket.create_connection(("127.0.0.1", port), timeout=BOUND) as conn:
        conn.sendall(what)
        try:
            while chunk := conn.recv(1024):
                answer += chunk
                if answer.endswith(b"\n"):
                    break
        except ConnectionResetError:
            pass  # a target that crashed on it
    return answer


def group_gone(pid: int) -> bool:
    try:
        os.killpg(pid, 0)
    except ProcessLookupError:
        return True
    return False


def gone(pid: int) -> bool:
    """Whether the process has ended (a zombie nobody reaped has ended too)."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return True
    return stat[stat.rindex(")") + 2] == "Z"


def test_tcp_target_is_ready_when_it_listens_and_stops(tmp_path: Path) -> None:
    port = free_port()
    target = TargetProcess(command(tmp_path, SERVE_TCP, port), ready=("127.0.0.1", port, "tcp"))
    target.start()
    assert ask(port) == b"hello\n"
    assert target.exited() is None
    usage = target.usage()
    assert usage.rss > 0
    assert usage.fds >= 3
    pid = target.pid
    assert pid is not None
    assert target.stop() is None
    assert target.stop() is None  # idempotent
    assert target.exited() is None  # stopped by us: no crash
    assert group_gone(pid)
    assert target.usage().rss == 0


def test_udp_target_is_ready_once_its_socket_is_bound(tmp_path: Path) -> None:
    port = free_port(socket.SOCK_DGRAM)
    ready = ("127.0.0.1", port, "udp")
    with TargetProcess(command(tmp_path, SERVE_UDP, port), ready=ready) as target:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as client:
            client.settimeout(BOUND)
            client.sendto(b"ping", ("127.0.0.1", port))  # bound already: it is not lost
            assert client.recvfrom(2048)[0] == b"ping"
        assert target.exited() is None
    assert target.pid is not None
    assert group_gone(target.pid)


def test_exit_status_and_stderr_are_kept(tmp_path: Path) -> None:
    target = TargetProcess(command(tmp_path, EXIT_3), ready=None)
    target.start()
    ended = until(target.exited)
    assert ended.status == 3
    assert ended.signal is None
    assert ended.stderr_tail == "bad config: no such site\n"
    assert ended.text() == "exited with status 3"
    assert target.stop() == ended  # it had ended by itself
    assert target.stop() == ended


def test_exit_before_ready_is_not_ready_with_the_tail(tmp_path: Path) -> None:
    port = free_port()
    line = command(tmp_path, EXIT_3)
    target = TargetProcess(line, ready=("127.0.0.1", port, "tcp"))
    with pytest.raises(TargetNotReady) as raised:
        target.start()
    message = str(raised.value)
    assert line in message
    assert f"tcp 127.0.0.1:{port}" in message
    assert "exited with status 3" in message
    assert "bad config: no such site" in message
    assert raised.value.exit is not None
    assert raised.value.exit.status == 3


def test_never_ready_is_stopped_and_told(tmp_path: Path) -> None:
    port = free_port(socket.SOCK_DGRAM)
    line = command(tmp_path, NEVER_READY)
    target = TargetProcess(line, ready=("127.0.0.1", port, "udp"), ready_timeout=0.5)
    with pytest.raises(TargetNotReady) as raised:
        target.start()
    message = str(raised.value)
    assert line in message
    assert f"did not listen on udp 127.0.0.1:{port} within 0.5 s" in message
    assert "warming up" in message
    assert raised.value.exit is None
    assert target.pid is not None
    assert group_gone(target.pid)
    assert target.exited() is None


def test_a_command_that_cannot_start(tmp_path: Path) -> None:
    missing = tmp_path / "no-such-program"
    target = TargetProcess(f"{missing} --port 1", ready=None)
    with pytest.raises(TargetNotReady, match="could not start"):
        target.start()
    for line in ("", "   ", "echo 'unclosed"):
        with pytest.raises(TargetCommandError):
            TargetProcess(line, ready=None)
    with pytest.raises(ValueError, match="transport"):
        TargetProcess("true", ready=("127.0.0.1", 1, "sctp"))


def test_a_crash_is_told_and_restart_counts(tmp_path: Path) -> None:
    port = lasting_port()
    target = TargetProcess(command(tmp_path, CRASH_ON_ASK, port), ready=("127.0.0.1", port, "tcp"))
    with target:
        for restarts in (1, 2):
            assert ask(port, b"crash") == b""
            ended = until(target.exited)
            assert ended.status == -signal.SIGSEGV
            assert ended.signal == "SIGSEGV"
            assert ended.text() == "killed by SIGSEGV"
            assert "crashing now" in ended.stderr_tail
            assert target.restart() == ended
            assert target.restarts == restarts
            assert target.exited() is None  # the new start runs
        assert target.restart() is None  # it ran: stopped, not ended by itself
        assert target.restarts == 3
        assert target.exited() is None


def test_stderr_tail_is_bounded_and_starts_at_a_line(tmp_path: Path) -> None:
    target = TargetProcess(command(tmp_path, NOISY), ready=None, kept=1000)
    target.start()
    ended = until(target.exited)
    assert ended.status == 1
    assert len(ended.stderr_tail.encode()) <= 1000
    assert ended.stderr_tail.startswith("line ")
    assert ended.stderr_tail.endswith("line 4999\n")


def test_the_tree_counts_a_child(tmp_path: Path) -> None:
    port = free_port()
    with TargetProcess(
        command(tmp_path, WITH_CHILD, port), ready=("127.0.0.1", port, "tcp")
    ) as target:
        assert target.pid is not None
        tree = process_tree(target.pid)
        assert len(tree) == 2
        assert sorted(_tree_by_parents(target.pid)) == sorted(tree)
        usage = target.usage()
        assert usage.rss > 20 * MiB
        child = tree[1]
    until(lambda: gone(child) or None)  # stopped with its parent's group


def test_a_leak_per_connection_is_found(tmp_path: Path) -> None:
    port = free_port()
    rss_watch = LeakWatch(warm_up=0, rss_limit=10 * MiB, fd_limit=10**6)
    fd_watch = LeakWatch(warm_up=0, rss_limit=2**40, fd_limit=10)
    with TargetProcess(command(tmp_path, LEAKY, port), ready=("127.0.0.1", port, "tcp")) as target:
        # One answer first: the target, one connection at a time, has closed start()'s probe
        # by then, so the samples' first count does not hold it (it gave 19 where 20 grew).
        assert ask(port, b"more") == b"ok\n"
        for _ in range(20):
            usage = target.usage()
            rss_watch.add(usage)
            fd_watch.add(usage)
            assert ask(port, b"more") == b"ok\n"
        usage = target.usage()
        rss_watch.add(usage)
        fd_watch.add(usage)
    leak = rss_watch.judge()
    assert leak is not None
    assert leak.what == "rss"
    assert leak.grew > 30 * MiB
    assert leak.text.startswith("RSS grew ")
    assert leak.text.endswith(" after warm-up, still rising at the end")
    leak = fd_watch.judge()
    assert leak is not None
    assert leak.what == "fds"
    assert leak.grew == 20
    assert leak.text.startswith("Open descriptors grew by 20 over ")


def test_growing_once_is_no_leak(tmp_path: Path) -> None:
    port = free_port()
    watch = LeakWatch(warm_up=0, rss_limit=10 * MiB, fd_limit=10)
    with TargetProcess(command(tmp_path, ONCE, port), ready=("127.0.0.1", port, "tcp")) as target:
        for _ in range(20):
            watch.add(target.usage())
            assert ask(port, b"more") == b"ok\n"
        last = target.usage()
        watch.add(last)
    assert last.rss > 30 * MiB
    assert watch.judge() is None


def samples(rss: list[int], fds: list[int] | None = None, step: float = 1.0) -> list[Usage]:
    return [
        Usage(number * step, size, 10 if fds is None else fds[number])
        for number, size in enumerate(rss)
    ]


def test_warm_up_is_ignored_and_reset_forgets() -> None:
    watch = LeakWatch(warm_up=5.0, rss_limit=MiB)
    for usage in samples([n * MiB for n in range(50)] + [50 * MiB] * 20, step=0.1):
        watch.add(usage)  # 49 MiB more in the first 5 s, then flat up to 6.9 s
    assert watch.judge() is None
    for n in range(1, 40):
        watch.add(Usage(7.0 + n, (50 + n) * MiB, 10))
    leak = watch.judge()
    assert leak is not None
    assert leak.grew == 39 * MiB  # from the first sample after warm-up, at 5 s
    assert leak.text == "RSS grew 39.0 MiB over 41 s after warm-up, still rising at the end"
    watch.reset()
    assert len(watch) == 0
    assert watch.judge() is None


def test_too_few_samples_are_not_judged() -> None:
    watch = LeakWatch(warm_up=0, rss_limit=1)
    for usage in samples([0, 10, 20, 30, 40, 50, 60]):
        watch.add(usage)
    assert watch.judge() is None
    watch.add(Usage(7.0, 70, 10))
    assert watch.judge() is not None


def test_the_watch_keeps_few_samples_evenly() -> None:
    watch = LeakWatch(warm_up=0, rss_limit=MiB, samples=16)
    for usage in samples([n * 2**12 for n in range(10_001)], step=0.01):
        watch.add(usage)
        assert len(watch) < 16
    leak = watch.judge()
    assert leak is not None
    assert leak.grew == 10_000 * 2**12  # the newest sample is judged, though not kept
    assert leak.text == "RSS grew 39.1 MiB over 100 s after warm-up, still rising at the end"


@given(st.integers(0, 2**32), st.lists(st.integers(0, MiB), min_size=8, max_size=300))
def test_flat_is_never_a_leak(level: int, noise: list[int]) -> None:
    watch = LeakWatch(warm_up=0, rss_limit=2 * MiB, fd_limit=5)
    for usage in samples([level + jitter for jitter in noise]):
        watch.add(usage)
    assert watch.judge() is None


@given(st.integers(8, 300), st.integers(8, 200), st.integers(1, 10 * MiB))
def test_steady_growth_past_the_limit_is_a_leak(count: int, limit: int, over: int) -> None:
    total = limit + over
    grown = [round(n * total / (count - 1)) for n in range(count)]
    watch = LeakWatch(warm_up=0, rss_limit=limit, fd_limit=10**9)
    for usage in samples(grown):
        watch.add(usage)
    leak = watch.judge()
    assert leak is not None
    assert (leak.what, leak.grew) == ("rss", total)
    watch = LeakWatch(warm_up=0, rss_limit=2**40, fd_limit=limit)
    for usage in samples([MiB] * count, grown):
        watch.add(usage)
    leak = watch.judge()
    assert leak is not None
    assert (leak.what, leak.grew) == ("fds", total)


@given(st.integers(8, 300), st.data())
def test_one_step_is_never_a_leak(count: int, data: st.DataObject) -> None:
    at = data.draw(st.integers(1, count - 1))
    size = data.draw(st.integers(2 * MiB, 2**32))
    watch = LeakWatch(warm_up=0, rss_limit=MiB, fd_limit=1)
    steps = [0 if n < at else size for n in range(count)]
    for usage in samples(steps, [10 if n < at else 500 for n in range(count)]):
        watch.add(usage)
    assert watch.judge() is None


def test_exit_text() -> None:
    assert Exit(1, None, "").text() == "exited with status 1"
    assert Exit(-6, "SIGABRT", "").text() == "killed by SIGABRT"
