"""The process monitor of `rcmlconf fuzz --target-command CMD`.

Like boofuzz's process monitor, the fuzzer starts the target itself. It restarts the target after
a crash. It keeps the target's exit status and the tail of its stderr, for the finding.

It also samples the memory and the open descriptors of the target's process tree. `LeakWatch`
reads those samples for the leak oracle: after a warm-up, growth past a limit that is still
rising at the end of the run.

Linux only: the tree, its memory, its descriptors and its UDP sockets are read from /proc.

Every call blocks. `start` waits up to `ready_timeout` seconds for the target to listen. `stop`
waits up to `STOP_GRACE` seconds for it to end on SIGTERM, and a little more after SIGKILL.
From an event loop, call them in a thread (`asyncio.to_thread`).
"""

from __future__ import annotations

import contextlib
import ctypes
import itertools
import os
import shlex
import signal
import socket
import subprocess
import threading
import time
from collections import deque
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType
from typing import Literal, Self

from rcmlconf.errors import RcmlconfError

#: How long a stopped target has, after SIGTERM to its process group, before SIGKILL.
STOP_GRACE = 2.0
#: The pause between two looks at whether a starting target listens yet.
READY_POLL = 0.02
#: How long to wait, once the target has ended, for the last of its stderr to be read.
READER_GRACE = 1.0
#: The bytes asked of the stderr pipe at a time.
READ_SIZE = 65536
#: The lines of stderr a TargetNotReady message ends with (its `stderr_tail` has them all).
TOLD_LINES = 20


class TargetCommandError(RcmlconfError, ValueError):
    """A --target-command that cannot be run as written."""


class TargetNotReady(RcmlconfError):
    """The target did not start, ended before it listened, or did not listen in time.

    `exit` is how it ended, when it ended by itself. `stderr_tail` is the last of its stderr.
    """

    def __init__(self, message: str, *, exit: Exit | None, stderr_tail: str) -> None:
        super().__init__(message)
        self.exit = exit
        self.stderr_tail = stderr_tail


@dataclass(frozen=True, slots=True)
class Exit:
    """How the target ended by itself.

    `status` is its exit code, or -N when signal N killed it (the subprocess module's rule).
    `signal` names that signal ("SIGSEGV"), and is None for a normal exit.
    `stderr_tail` is the last lines of its stderr: at most `kept` bytes, decoded from UTF-8
    with errors replaced.
    """

    status: int
    signal: str | None
    stderr_tail: str

    def text(self) -> str:
        """How it ended, in a few words: "exited with status 1" or "killed by SIGSEGV"."""
        if self.signal is not None:
            return f"killed by {self.signal}"
        return f"exited with status {self.status}"


@dataclass(frozen=True, slots=True)
class Usage:
    """One sample of what the target's process tree holds.

    `at` is the time of the sample, by `time.monotonic()`. `rss` is the resident memory in
    bytes, summed over the process and all its descendants (VmRSS of /proc/PID/status). `fds`
    is the number of open descriptors, summed over the same tree (the entries of /proc/PID/fd).
    """

    at: float
    rss: int
    fds: int


@dataclass(frozen=True, slots=True)
class Leak:
    """A leak the watch found.

    `what` is "rss" or "fds". `grew` is the growth over the watched run, in bytes or in
    descriptors. `text` says it in plain English, for the finding.
    """

    what: Literal["rss", "fds"]
    grew: int
    text: str


class _Run:
    """One start of the command: its process, and a reader that keeps the tail of its stderr.

    The reader is a daemon thread. It keeps at most `kept` bytes, the newest, in a ring.
    """

    def __init__(self, process: subprocess.Popen[bytes], kept: int) -> None:
        self.process = process
        #: Set once the monitor stopped this run: its end is then no crash.
        self.stopped = False
        #: Set once SIGKILL went to the run's group, after the run ended.
        self._cleaned = False
        self._kept = kept
        self._chunks: deque[bytes] = deque()
        self._size = 0
        self._dropped = False
        self._lock = threading.Lock()
        self._exit: Exit | None = None
        self._reader = threading.Thread(
            target=self._read, name=f"stderr of pid {process.pid}", daemon=True
        )
        self._reader.start()

    def _read(self) -> None:
        stream = self.process.stderr
        assert stream is not None
        try:
            while chunk := os.read(stream.fileno(), READ_SIZE):
                self._keep(chunk)
        except (OSError, ValueError):
            pass  # the pipe broke or was closed: the tail is what was read so far
        finally:
            with contextlib.suppress(OSError):
                stream.close()

    def _keep(self, chunk: bytes) -> None:
        with self._lock:
            self._chunks.append(chunk)
            self._size += len(chunk)
            while self._size > self._kept:
                excess = self._size - self._kept
                first = self._chunks[0]
                if len(first) <= excess:
                    self._chunks.popleft()
                    self._size -= len(first)
                else:
                    self._chunks[0] = first[excess:]
                    self._size -= excess
                self._dropped = True

    def tail(self) -> str:
        """The stderr kept so far. When older bytes were dropped, it starts at a line's start."""
        with self._lock:
            data = b"".join(self._chunks)
            dropped = self._dropped
        if dropped:
            newline = data.find(b"\n")
            if 0 <= newline < len(data) - 1:
                data = data[newline + 1 :]
        return data.decode("utf-8", errors="replace")

    def finish(self) -> None:
        """Wait a little for the reader to reach the end of the pipe.

        A descendant that left the process group may hold the pipe open. The wait is bounded,
        so the tail is then what was read by that time.
        """
        self._reader.join(READER_GRACE)

    def ended(self) -> Exit:
        """How the process ended. Call once it has ended; the answer is kept."""
        if self._exit is None:
            status = self.process.wait()
            self.finish()
            name = None
            if status < 0:
                try:
                    name = signal.Signals(-status).name
                except ValueError:
                    name = f"signal {-status}"
            self._exit = Exit(status, name, self.tail())
        return self._exit

    def signal_group(self, which: signal.Signals) -> None:
        """Send `which` to the run's process group, if anything of it is left."""
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.killpg(self.process.pid, which)

    def kill_leftovers(self) -> None:
        """Once the leader has ended, SIGKILL what is left of its group, once."""
        if not self._cleaned:
            self._cleaned = True
            self.signal_group(signal.SIGKILL)

    def halt(self) -> None:
        """Stop the run: SIGTERM to its group, then SIGKILL after `STOP_GRACE` seconds."""
        self.stopped = True
        self.signal_group(signal.SIGTERM)
        with contextlib.suppress(subprocess.TimeoutExpired):
            self.process.wait(STOP_GRACE)
        # Also the descendants that outlived the leader or ignore SIGTERM.
        self.kill_leftovers()
        with contextlib.suppress(subprocess.TimeoutExpired):
            self.process.wait(STOP_GRACE)
        self.finish()


class TargetProcess:
    """The target, started, watched and restarted by the fuzzer.

    `command` is one command line. It is split into words as a POSIX shell would split it
    (`shlex.split`), but no shell runs it: no pipes, redirections, variables or globs. To use
    those, write `sh -c '...'`; the exit status is then the shell's.

    The target runs in a session and process group of its own, in `cwd` when given. Its stdin
    and stdout are /dev/null. A daemon thread reads its stderr and keeps the last `kept` bytes.

    `ready` is the address the target serves, as (host, port, "tcp" or "udp"). When given,
    `start` returns only once the target listens there. For TCP, that is when a connection to
    it succeeds. The connection is closed at once, so the target sees one empty connection.
    For UDP, that is when a socket of the target's process tree is bound to the port. When
    `ready` is None, `start` returns as soon as the process runs.

    A TCP target that starts as another process already listens on its port looks ready at
    once. It then fails to bind and exits; `exited` says so.

    Use it as a context manager to have it started on entry and stopped on exit.
    """

    def __init__(
        self,
        command: str,
        *,
        ready: tuple[str, int, str] | None,
        ready_timeout: float = 10.0,
        kept: int = 16384,
        cwd: Path | None = None,
    ) -> None:
        try:
            words = shlex.split(command)
        except ValueError as error:
            raise TargetCommandError(f"{command!r} does not split into words: {error}") from None
        if not words:
            raise TargetCommandError("the target command is empty")
        if ready is not None:
            _, port, transport = ready
            if transport not in ("tcp", "udp"):
                raise ValueError(f"ready's transport is {transport!r}, not 'tcp' or 'udp'")
            if not 0 < port < 65536:
                raise ValueError(f"ready's port {port} is not a port")
        if ready_timeout < 0:
            raise ValueError(f"ready_timeout is {ready_timeout}, below 0")
        if kept < 1:
            raise ValueError(f"kept is {kept}, below 1")
        self.command = command
        self.words = tuple(words)
        self.ready = ready
        self.ready_timeout = ready_timeout
        self.kept = kept
        self.cwd = cwd
        #: How many times `restart` has started the target again.
        self.restarts = 0
        self._run: _Run | None = None

    @property
    def pid(self) -> int | None:
        """The process ID of the latest start, or None before the first."""
        return None if self._run is None else self._run.process.pid

    def start(self) -> None:
        """Start the target, and wait until it listens at `ready` (when given).

        Raises TargetNotReady when the command cannot start, when it ends before it listens, or
        when it does not listen within `ready_timeout` seconds. In that last case it is stopped
        first. Raises RuntimeError when the target runs already.
        """
        if self._run is not None:
            if self._run.process.poll() is None:
                raise RuntimeError(f"the target command {self._shown} is running already")
            # What is left of the earlier run's group might still hold the target's port.
            self._run.kill_leftovers()
        try:
            process = subprocess.Popen(
                self.words,
                stdin=subprocess.DEVNULL,
                stdout=subprocess.DEVNULL,
                stderr=subprocess.PIPE,
                cwd=self.cwd,
                start_new_session=True,  # its own process group: stopped with its children
                preexec_fn=_die_with_parent,
            )
        except OSError as error:
            raise TargetNotReady(
                f"the target command {self._shown} could not start: {error.strerror or error}",
                exit=None,
                stderr_tail="",
            ) from None
        run = _Run(process, self.kept)
        self._run = run
        if self.ready is not None:
            self._await_ready(run, self.ready)

    def exited(self) -> Exit | None:
        """How the target ended by itself. None while it runs, and after `stop` stopped it."""
        run = self._run
        if run is None or run.stopped or run.process.poll() is None:
            return None
        return run.ended()

    def restart(self) -> Exit | None:
        """Start the target again: how it ended by itself, or None when it ran until now.

        A running target is stopped first. What is left of the earlier process group is
        killed. Each restart that starts the target adds one to `restarts`.
        """
        ended = self.exited()
        self.stop()
        self.start()
        self.restarts += 1
        return ended

    def stop(self) -> Exit | None:
        """Stop the target and its process group.

        The group gets SIGTERM, then SIGKILL after up to `STOP_GRACE` seconds. Returns how the
        target ended if it had ended by itself before the first stop, else None. Calling it
        again gives the same answer and sends nothing more to a stopped group.
        """
        run = self._run
        if run is None or run.stopped:
            return None
        if run.process.poll() is not None:
            ended = run.ended()
            run.kill_leftovers()  # descendants it left behind
            return ended
        run.halt()
        return None

    def usage(self) -> Usage:
        """What the target's process tree holds now: its memory and open descriptors.

        The tree is the target and all its descendants, found through each thread's
        /proc/PID/task/TID/children. A process that vanishes while it is read is left out.
        A target that is not running holds nothing (0 and 0).
        """
        now = time.monotonic()
        run = self._run
        if run is None or run.process.poll() is not None:
            return Usage(now, 0, 0)
        rss = fds = 0
        for pid in process_tree(run.process.pid):
            held = _held(pid)
            if held is not None:
                rss += held[0]
                fds += held[1]
        return Usage(now, rss, fds)

    def __enter__(self) -> Self:
        self.start()
        return self

    def __exit__(
        self,
        kind: type[BaseException] | None,
        error: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        self.stop()

    @property
    def _shown(self) -> str:
        return shlex.join(self.words)

    def _await_ready(self, run: _Run, ready: tuple[str, int, str]) -> None:
        host, port, transport = ready
        where = f"{transport} {host}:{port}"
        deadline = time.monotonic() + self.ready_timeout
        while True:
            if run.process.poll() is not None:
                ended = run.ended()
                raise TargetNotReady(
                    f"the target command {self._shown} {ended.text()} before it listened"
                    f" on {where}{_told(ended.stderr_tail)}",
                    exit=ended,
                    stderr_tail=ended.stderr_tail,
                )
            left = deadline - time.monotonic()
            if transport == "tcp":
                listening = _accepts(host, port, max(0.05, min(0.5, left)))
            else:
                listening = _udp_bound(port, tree_sockets(run.process.pid))
            if listening:
                return
            if time.monotonic() >= deadline:
                run.halt()
                tail = run.tail()
                raise TargetNotReady(
                    f"the target command {self._shown} did not listen on {where} within"
                    f" {self.ready_timeout:g} s{_told(tail)}",
                    exit=None,
                    stderr_tail=tail,
                )
            time.sleep(READY_POLL)


class LeakWatch:
    """The leak oracle: reads `Usage` samples of one run of the target and says if it leaks.

    Samples in the first `warm_up` seconds (from the first sample) are ignored: a target fills
    its caches and pools there. After that, memory (RSS) or descriptors leak when all three hold:

    - they grew by more than the limit (`rss_limit` bytes, `fd_limit` descriptors), from the
      first sample after warm-up to the last;
    - they still rise at the end: the mean of the last quarter of the samples is above the mean
      of the third quarter, and above the highest of the first half;
    - they grew in more than one step: no rise between two samples is more than half the growth.

    So a target that grew once and then stayed flat does not leak, wherever in the run it grew.
    (Without the third rule, one step late in the run would look like a rise at the end.)

    The watch keeps at most `samples` samples. Past that it drops every other one, and keeps one
    in two from then on. So the kept samples stay evenly spread over the run. The newest sample
    is always judged.

    A restart of the target begins a new run: call `reset`.
    """

    #: Fewer samples after warm-up than this are too few to judge.
    MIN_SAMPLES = 8

    def __init__(
        self,
        *,
        warm_up: float = 5.0,
        rss_limit: int = 50 * 2**20,
        fd_limit: int = 100,
        samples: int = 1000,
    ) -> None:
        if samples < self.MIN_SAMPLES:
            raise ValueError(f"samples is {samples}, below {self.MIN_SAMPLES}")
        self.warm_up = warm_up
        self.rss_limit = rss_limit
        self.fd_limit = fd_limit
        self.samples = samples
        self.reset()

    def reset(self) -> None:
        """Forget every sample: the next one begins a new run, and a new warm-up."""
        self._began: float | None = None
        self._kept: list[Usage] = []
        self._newest: Usage | None = None
        self._stride = 1
        self._seen = 0

    def __len__(self) -> int:
        """How many samples the watch keeps now."""
        return len(self._kept)

    def add(self, usage: Usage) -> None:
        """Take one sample."""
        if self._began is None:
            self._began = usage.at
        if usage.at - self._began < self.warm_up:
            return
        self._newest = usage
        if self._seen % self._stride == 0:
            self._kept.append(usage)
            if len(self._kept) >= self.samples:
                self._kept = self._kept[::2]
                self._stride *= 2
        self._seen += 1

    def judge(self) -> Leak | None:
        """The leak the samples show so far, or None.

        When both memory and descriptors leak, the one furthest past its limit is told.
        """
        series = list(self._kept)
        if self._newest is not None and (not series or series[-1] is not self._newest):
            series.append(self._newest)
        if len(series) < self.MIN_SAMPLES:
            return None
        span = _seconds(series[-1].at - series[0].at)
        found: list[tuple[float, Leak]] = []
        rss = [sample.rss for sample in series]
        grew = rss[-1] - rss[0]
        if grew > self.rss_limit and _rising(rss) and _spread(rss, grew):
            text = f"RSS grew {_size(grew)} over {span} after warm-up, still rising at the end"
            found.append((grew / max(self.rss_limit, 1), Leak("rss", grew, text)))
        fds = [sample.fds for sample in series]
        grew = fds[-1] - fds[0]
        if grew > self.fd_limit and _rising(fds) and _spread(fds, grew):
            text = (
                f"Open descriptors grew by {grew} over {span} after warm-up,"
                " still rising at the end"
            )
            found.append((grew / max(self.fd_limit, 1), Leak("fds", grew, text)))
        if not found:
            return None
        return max(found, key=lambda pair: pair[0])[1]


def process_tree(root: int) -> list[int]:
    """The process `root` and all its descendants, by /proc/PID/task/TID/children.

    Where the kernel has no such files, the parents are read from /proc/PID/stat instead.
    """
    if not _HAS_CHILDREN_FILES:
        return _tree_by_parents(root)
    found: list[int] = []
    seen: set[int] = set()
    todo = [root]
    while todo:
        pid = todo.pop()
        if pid in seen:
            continue
        seen.add(pid)
        found.append(pid)
        todo.extend(_children(pid))
    return found


def tree_sockets(root: int) -> set[int]:
    """The inodes of the sockets open in the process tree of `root`."""
    inodes: set[int] = set()
    for pid in process_tree(root):
        fd_dir = f"/proc/{pid}/fd"
        try:
            names = os.listdir(fd_dir)
        except OSError:
            continue
        for name in names:
            try:
                link = os.readlink(f"{fd_dir}/{name}")
            except OSError:
                continue
            if link.startswith("socket:[") and link.endswith("]"):
                inodes.add(int(link[8:-1]))
    return inodes


def _children(pid: int) -> list[int]:
    try:
        tasks = os.listdir(f"/proc/{pid}/task")
    except OSError:
        return []
    children: list[int] = []
    for task in tasks:
        try:
            with open(f"/proc/{pid}/task/{task}/children") as file:
                children.extend(int(word) for word in file.read().split())
        except (OSError, ValueError):
            continue
    return children


def _tree_by_parents(root: int) -> list[int]:
    parents: dict[int, list[int]] = {}
    for name in os.listdir("/proc"):
        if not name.isdigit():
            continue
        try:
            with open(f"/proc/{name}/stat") as file:
                stat = file.read()
            # The command name, in parentheses, may hold spaces and parentheses itself.
            parent = int(stat[stat.rindex(")") + 2 :].split()[1])
        except (OSError, ValueError, IndexError):
            continue
        parents.setdefault(parent, []).append(int(name))
    found: list[int] = []
    seen: set[int] = set()
    todo = [root]
    while todo:
        pid = todo.pop()
        if pid in seen:
            continue
        seen.add(pid)
        found.append(pid)
        todo.extend(parents.get(pid, []))
    return found


def _held(pid: int) -> tuple[int, int] | None:
    """The RSS in bytes and the open descriptors of one process; None if it vanished."""
    try:
        with open(f"/proc/{pid}/status") as file:
            status = file.read()
        fds = len(os.listdir(f"/proc/{pid}/fd"))
    except OSError:
        return None
    rss = 0  # a zombie has no VmRSS line: it holds no memory
    for line in status.splitlines():
        if line.startswith("VmRSS:"):
            rss = int(line.split()[1]) * 1024  # the kernel writes kB, meaning KiB
            break
    return rss, fds


def _accepts(host: str, port: int, timeout: float) -> bool:
    try:
        with socket.create_connection((host, port), timeout=timeout):
            return True
    except OSError:
        return False


def _udp_bound(port: int, inodes: set[int]) -> bool:
    """Whether one of the sockets `inodes` is a UDP socket bound to `port`."""
    if not inodes:
        return False
    for table in ("/proc/net/udp", "/proc/net/udp6"):
        try:
            with open(table) as file:
                lines = file.read().splitlines()[1:]
        except OSError:
            continue
        for line in lines:
            fields = line.split()
            try:
                bound = int(fields[1].rsplit(":", 1)[1], 16)
                inode = int(fields[9])
            except (IndexError, ValueError):
                continue
            if bound == port and inode in inodes:
                return True
    return False


def _rising(values: list[int]) -> bool:
    """Whether the series still rises at its end (see LeakWatch)."""
    count = len(values)
    first_half = values[: count // 2]
    third = values[count // 2 : 3 * count // 4]
    last = values[3 * count // 4 :]
    end = sum(last) / len(last)
    return end > sum(third) / len(third) and end > max(first_half)


def _spread(values: list[int], grew: int) -> bool:
    """Whether no rise between two samples is more than half the growth `grew`."""
    steepest = max(later - earlier for earlier, later in itertools.pairwise(values))
    return 2 * steepest <= grew


def _size(count: int) -> str:
    if abs(count) >= 2**20:
        return f"{count / 2**20:.1f} MiB"
    if abs(count) >= 2**10:
        return f"{count / 2**10:.1f} KiB"
    return f"{count} bytes"


def _seconds(span: float) -> str:
    return f"{span:.0f} s" if span >= 10 else f"{span:.1f} s"


def _told(tail: str) -> str:
    """The last `TOLD_LINES` lines of the stderr tail, to end a message with."""
    lines = tail.rstrip().splitlines()[-TOLD_LINES:]
    if not lines:
        return "; its stderr was empty"
    return "; its stderr ended with:\n" + "\n".join(f"  | {line}" for line in lines)


def _has_children_files() -> bool:
    pid = os.getpid()
    return os.path.exists(f"/proc/{pid}/task/{pid}/children")


_HAS_CHILDREN_FILES = _has_children_files()


#: prctl(2)'s PR_SET_PDEATHSIG.
_PR_SET_PDEATHSIG = 1


def _die_with_parent() -> None:
    """In the target's process, before it runs: SIGTERM it when the fuzzer dies, so that a
    fuzzer killed (a CI job's timeout) leaves no target behind holding its port."""
    with contextlib.suppress(OSError, AttributeError):
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, signal.SIGTERM)
