"""README's tour, run as a newcomer runs it: every `$ rcmlconf ...` line of its console blocks.

Each example runs as a real process in a folder laid out as the repository is (so relative paths
and the paths printed are README's), in the order README gives them: `serve` and `robot` keep
running for the examples after them, on ports this test picks (README's 7330 and 7340 are
rewritten to them). An example must exit as README implies (1 where it shows a refusal, a FAIL
or an invalid file; 0 otherwise), and every line README shows for it must appear in what it
printed, in order, with numbers, times and identifiers free to differ. README can no longer show
a command that fails.
"""

from __future__ import annotations

import re
import shlex
import signal
import socket
import subprocess
import time
from dataclasses import dataclass, field
from pathlib import Path

import pytest
from support.processes import BOUND, COMMAND

ROOT = Path(__file__).resolve().parent.parent
README = ROOT / "README.md"

#: Commands that serve until stopped: started, kept for the later examples, stopped at the end.
SERVERS = {"serve": "--port", "robot": "--port"}
#: Examples that run until Ctrl-C: interrupted after this long, and then they must end cleanly.
UNTIL_INTERRUPTED = {"watch": 1.5}
#: README's `sh` blocks that are templates or need what a test cannot have, and why. Every other
#: `$ rcmlconf` line is run; a new example is run unless it is named here.
NOT_RUN = {
    "rcmlconf run --target 127.0.0.1:7330 --rcml robot.rcml": "a template: the user's robot",
    "rcmlconf sniff": "needs root or CAP_NET_RAW, and traffic on lo",
    "rcmlconf run --role client --listen 7330": "a template: the user's client is tested",
    "rcmlconf fuzz --seconds 60": "a minute of fuzzing; tests/fuzz run it with short budgets",
    "rcmlconf fuzz --fault": "tests/fuzz/test_fuzz_cli.py runs it, and replays its finding",
    "rcmlconf fuzz --target": "a template: the user's server, started by its own command",
    "rcmlconf fuzz replay": "a template: a finding of the campaign above",
    "rcmlconf fuzz --resume": "a template: the campaign above, resumed",
    "rcmlconf fuzz --model": "a minute of fuzzing; tests/fuzz run the robot with short budgets",
    "rcmlconf fuzz --rsp-target": "a template: the user's robot, started by its own command",
    "rcmlconf fuzz --role client": "tests/fuzz/test_client_role.py runs it with short budgets",
    "rcmlconf fuzz --role local": "tests/foreign/test_fuzz_bugs.py runs it with short budgets",
}


@dataclass
class Example:
    line: int
    command: str
    shown: list[str] = field(default_factory=list)

    @property
    def words(self) -> list[str]:
        return shlex.split(self.command, comments=True)

    @property
    def verb(self) -> str:
        """The command, or the subcommand of `client URL COMMAND` and `rsp COMMAND`."""
        words = [w for w in self.words[1:] if not w.startswith("-")]
        at = {"client": 2, "rsp": 1}.get(words[0], 0)
        return words[at]

    @property
    def refuses(self) -> bool:
        """README shows a refusal, a failing case or an invalid file: exit status 1."""
        return any(
            line.startswith(("rcmlconf ", "FAIL ")) or ": error: " in line for line in self.shown
        )


def examples() -> list[Example]:
    """The `$ rcmlconf` lines of README's console blocks, with the output shown under each."""
    found: list[Example] = []
    block: str | None = None
    pending = ""
    for number, text in enumerate(README.read_text().splitlines(), 1):
        if text.startswith("```"):
            block = text[3:] if block is None else None
            continue
        if block != "console":
            continue
        if pending or text.startswith("$ rcmlconf "):
            pending += text.removeprefix("$ ").strip()
            if pending.endswith("\\"):
                pending = pending[:-1] + " "
                continue
            found.append(Example(number, pending))
            pending = ""
        elif found and text.strip() != "...":
            found[-1].shown.append(text)
    return found


def sh_commands() -> list[str]:
    """The `rcmlconf` lines of README's sh blocks (what a user copies into a script)."""
    commands, block = [], None
    for text in README.read_text().splitlines():
        if text.startswith("```"):
            block = text[3:] if block is None else None
        elif block == "sh" and text.startswith("rcmlconf "):
            commands.append(text)
    return commands


_VARYING = re.compile(r"[0-9a-f]*[0-9][0-9a-f]*(?:[.,:][0-9a-f]+)*|\s+")


def shape(line: str) -> str:
    """A line with its numbers, hex identifiers and runs of blanks made alike."""
    return _VARYING.sub(lambda m: " " if m.group().isspace() else "#", line).strip()


def matches(shown: str, printed: str) -> bool:
    """`printed` is the line README shows, where README's `...` stands for any text."""
    parts = [re.escape(part.strip()) for part in shape(shown).split("...")]
    return re.fullmatch(".*".join(parts), shape(printed)) is not None


def shown_in_order(shown: list[str], *outputs: str) -> list[str]:
    """The lines README shows that were not printed: each must be a line of one of `outputs`
    (standard output and error, whose lines interleave as they please), in order within it."""
    streams = [output.splitlines() for output in outputs]
    cursors = [0] * len(streams)
    missing = []
    for line in shown:
        for which, lines in enumerate(streams):
            at = next(
                (i for i in range(cursors[which], len(lines)) if matches(line, lines[i])), None
            )
            if at is not None:
                cursors[which] = at + 1
                break
        else:
            missing.append(line)
    return missing


#: How many pairs of ports a server of the tour is given before the test gives up.
PORT_TRIES = 5


def free_port_pair() -> int:
    """A port P with TCP P, UDP P and TCP P+1 free: RCTP, its data stream, its files."""
    for _ in range(50):
        with socket.socket() as probe:
            probe.bind(("127.0.0.1", 0))
            port = probe.getsockname()[1]
        try:
            with (
                socket.socket() as a,
                socket.socket(type=socket.SOCK_DGRAM) as b,
                socket.socket() as c,
            ):
                a.bind(("127.0.0.1", port))
                b.bind(("127.0.0.1", port))
                c.bind(("127.0.0.1", port + 1))
        except OSError:
            continue
        return port
    raise AssertionError("no free pair of ports on 127.0.0.1")


@pytest.fixture
def tour(tmp_path: Path) -> Path:
    """A folder laid out as the repository is, with nothing written into the real one."""
    for name in ("rcmlconf", "vectors", "captures"):
        (tmp_path / name).symlink_to(ROOT / name)
    return tmp_path


class Tour:
    def __init__(self, folder: Path) -> None:
        self.folder = folder
        self.ports = {"7330": str(free_port_pair()), "7340": str(free_port_pair())}
        self.servers: list[subprocess.Popen[str]] = []

    def words(self, example: Example) -> list[str]:
        words = [self._ported(word) for word in example.words[1:]]
        if example.verb in SERVERS:
            port = self.ports["7330" if example.verb == "serve" else "7340"]
            words += [SERVERS[example.verb], port]
        if "--robot" in words:
            at = words.index("--robot") + 1
            words[at] += f":{self.ports['7340']}"
        return words

    def _ported(self, word: str) -> str:
        for readme_port, port in self.ports.items():
            word = word.replace(f"127.0.0.1:{readme_port}", f"127.0.0.1:{port}")
        return word

    def start(self, example: Example) -> None:
        # Ports picked free can be taken before the server binds them (other tests run beside
        # this one): a server that finds its port in use gets another pair, a few times.
        for _ in range(PORT_TRIES):
            ready = self.folder / f"ready-{len(self.servers)}.json"
            process = subprocess.Popen(
                [*COMMAND, *self.words(example), "--ready-file", str(ready)],
                cwd=self.folder,
                stdout=subprocess.PIPE,
                stderr=subprocess.PIPE,
                text=True,
            )
            self.servers.append(process)
            deadline = time.monotonic() + BOUND
            while not ready.exists() and process.poll() is None:
                assert time.monotonic() < deadline, f"README line {example.line} never got ready"
                time.sleep(0.02)
            if ready.exists():
                return
            out, err = process.communicate()
            assert "address already in use" in err, (example.command, (out, err))
            self.ports["7330" if example.verb == "serve" else "7340"] = str(free_port_pair())
        raise AssertionError(f"README line {example.line}: its ports were taken {PORT_TRIES} times")

    def run(self, example: Example) -> subprocess.CompletedProcess[str]:
        process = subprocess.Popen(
            [*COMMAND, *self.words(example)],
            cwd=self.folder,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        interrupt_after = UNTIL_INTERRUPTED.get(example.verb)
        if interrupt_after is not None:
            try:
                process.wait(interrupt_after)
            except subprocess.TimeoutExpired:
                process.send_signal(signal.SIGINT)
        try:
            out, err = process.communicate(timeout=BOUND * 3)
        except subprocess.TimeoutExpired:
            process.kill()
            out, err = process.communicate()
            raise AssertionError(f"README line {example.line} did not end: {err}") from None
        return subprocess.CompletedProcess(process.args, process.returncode, out, err)

    def stop(self) -> None:
        for process in self.servers:
            if process.poll() is None:
                process.send_signal(signal.SIGINT)
        for process in self.servers:
            try:
                _, err = process.communicate(timeout=BOUND)
            except subprocess.TimeoutExpired:
                process.kill()
                raise AssertionError("a server of the tour did not stop on Ctrl-C") from None
            assert "Traceback" not in err, err


def test_readme_shows_examples() -> None:
    """The tour is found at all: the test below cannot pass by reading nothing."""
    verbs = {example.verb for example in examples()}
    assert {"run", "validate", "serve", "read", "stream", "watch", "robot", "local"} <= verbs
    assert {"dissect", "generate"} <= verbs


#: How many more times an example runs when it missed a line README shows and its own summary
#: says some case was inconclusive: the tests run on two workers beside it, and a case starved of
#: CPU honestly says inconclusive, where README shows a quiet machine's run. A miss without an
#: inconclusive, or inconclusive every time, still fails.
RERUNS_WHEN_INCONCLUSIVE = 2

_SOME_INCONCLUSIVE = re.compile(r" results: .*\b[1-9][0-9]* inconclusive\b")


def what_is_wrong(example: Example, done: subprocess.CompletedProcess[str]) -> str | None:
    """What README's example did not do as shown, or None."""
    printed = done.stdout + done.stderr
    where = f"README line {example.line}: {example.command}"
    expected = 1 if example.refuses else 0
    if done.returncode != expected:
        return f"{where}: exit {done.returncode}, not {expected}:\n{printed}"
    if "Traceback" in printed or "bug in rcmlconf" in printed:
        return f"{where}: an internal error:\n{printed}"
    if missing := shown_in_order(example.shown, done.stdout, done.stderr):
        return f"{where}: README shows lines it did not print: {missing}\n{printed}"
    return None


def test_every_tour_example_works_as_shown(tour: Path) -> None:
    player = Tour(tour)
    failures: list[str] = []
    try:
        for example in examples():
            if example.verb in SERVERS:
                player.start(example)
                continue
            done = player.run(example)
            wrong = what_is_wrong(example, done)
            for _ in range(RERUNS_WHEN_INCONCLUSIVE):
                if wrong is None or not _SOME_INCONCLUSIVE.search(done.stdout + done.stderr):
                    break
                done = player.run(example)
                wrong = what_is_wrong(example, done)
            if wrong is not None:
                failures.append(wrong)
    finally:
        player.stop()
    assert not failures, "\n\n".join(failures)


def test_every_sh_example_is_run_or_named(tour: Path) -> None:
    """The `sh` blocks' commands: run each one that can be (from a folder laid out as the
    repository), and the rest are named in NOT_RUN with the reason."""
    for command in sh_commands():
        if any(command.startswith(prefix) for prefix in NOT_RUN):
            continue
        done = subprocess.run(
            [*COMMAND, *shlex.split(command, comments=True)[1:]],
            cwd=tour,
            capture_output=True,
            text=True,
            timeout=BOUND,
            check=False,
        )
        assert done.returncode == 0, (command, done.stderr)
        assert "Traceback" not in done.stderr
