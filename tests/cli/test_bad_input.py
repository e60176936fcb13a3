"""Every command, fed the bad input a newcomer or a script gives it, answers in one located line.

Each row is one bad input to one command, and the text its answer must name (the option, the
file or the value). Each runs as a real process, as a user runs it, and must end with status 1
or 2, a line on standard error that names the input, and no traceback or "bug in rcmlconf". The
addresses are on 127.0.0.1 where nothing listens (port 9, discard, over UDP gets no answer), so
a command that opens a session before checking its options is caught by its answer, not by a
robot that happens to run.
"""

from __future__ import annotations

import subprocess
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import pytest
from support.processes import BOUND, COMMAND

from rcmlconf.cli.console import printable

ROOT = Path(__file__).resolve().parents[2]
CUBO = str(ROOT / "rcmlconf/reference/robots/cubo/cubo.rmodel")
CAMERA = str(ROOT / "rcmlconf/reference/robots/camera/camera.rcml")
CAPTURE = str(ROOT / "captures/rctp-session.pcap")
NOWHERE = "/nonexistent-rcmlconf/d"
#: Non-finite and out-of-range numbers every float option must refuse.
NUMBERS = ("nan", "inf", "-inf", "1e309", "-1")


@dataclass(frozen=True)
class Bad:
    args: tuple[str, ...]
    #: What the answer must name: the option, the argument's file or the value.
    names: str

    @property
    def id(self) -> str:
        return " ".join(self.args)[:80]


def files(folder: Path) -> dict[str, Path]:
    """Bad files of every kind, by what they are."""
    made = {
        "empty": folder / "empty.x",
        "binary": folder / "binary.x",
        "huge": folder / "huge.x",
        "newline name": folder / "new\nline.x",
        "dash name": folder / "-dash.x",
        "not utf-8 name": folder / "bad\udcff.x",
        "garbage toml": folder / "garbage.toml",
        "garbage json": folder / "garbage.json",
    }
    made["empty"].write_bytes(b"")
    made["binary"].write_bytes(bytes(range(256)) * 64)
    made["huge"].write_bytes(b"<" * (17 * 1024 * 1024))  # past the 16 MiB document bound
    made["newline name"].write_bytes(b"\0\1\2")
    made["dash name"].write_bytes(b"\0\1\2")
    made["not utf-8 name"].write_bytes(b"\0\1\2")
    made["garbage toml"].write_text("a = [\n")
    made["garbage json"].write_text('{"results": ')
    made["directory"] = folder / "dir.x"
    made["directory"].mkdir()
    made["missing"] = folder / "missing.x"
    made["through a file"] = made["empty"] / "x"
    return made


BAD_FILES = (
    "empty",
    "binary",
    "newline name",
    "dash name",
    "not utf-8 name",
    "directory",
    "missing",
    "through a file",
)


def bad_files(
    *before: str,
    after: tuple[str, ...] = (),
    option: str | None = None,
    kinds: tuple[str, ...] = BAD_FILES,
) -> list[Bad]:
    """The command with each bad file as its argument, or as `option`'s value."""
    return [
        Bad((*before, *((option,) if option else ()), f"{{{kind}}}", *after), kind)
        for kind in kinds
    ]


#: An empty ICS declares nothing missing, and an empty baseline lists no known failure (what CI
#: has once every failure is fixed): both are valid.
NOT_EMPTY = tuple(kind for kind in BAD_FILES if kind != "empty")


def bad_numbers(*before: str, option: str, after: tuple[str, ...] = ()) -> list[Bad]:
    return [Bad((*before, option, number, *after), option) for number in NUMBERS]


def json_file(folder: Path, name: str, text: str) -> str:
    path = folder / name
    path.write_text(text)
    return str(path)


def sweep(folder: Path) -> dict[str, list[Bad]]:
    client = ("client", "rctp://127.0.0.1:9/camera")
    local = ("local", CUBO, "--robot", "127.0.0.1:9")
    baselines = {
        "baseline-string.json": '{"results": "x"}',
        "baseline-items.json": '{"results": [5, null]}',
        "baseline-list.json": "[1, 2, 3]",
        "baseline-null.json": "null",
        "baseline-ids.json": '{"results": [{"id": 5}]}',
    }
    return {
        "validate": [
            *bad_files("validate"),
            Bad(("validate", "{huge}"), "huge"),
            Bad(("validate", str(folder / "dir.x")), "dir.x"),
            Bad(("validate", "--max-findings", "-1", CUBO), "--max-findings"),
            Bad(("validate", "--map", "garbage", CUBO), "--map"),
            Bad(("validate", "--format", "nope", CUBO), "--format"),
        ],
        "dissect": [
            *bad_files("dissect"),
            Bad(("dissect", "{huge}"), "huge"),
            *bad_files("dissect", option="--model", after=(CAPTURE,)),
            *(
                Bad(("dissect", "--decode-as", spec, CAPTURE), "--decode-as")
                for spec in ("x", "rsp=-1", "rsp=70000", "nope=1", "rsp=nan", "rsp=")
            ),
            Bad(("dissect", "--plot", f"{NOWHERE}/p.png", CAPTURE), "p.png"),
            Bad(("dissect", "--plot", str(folder / "dir.x"), CAPTURE), "dir.x"),
        ],
        "wireshark": [
            Bad(("wireshark", "-o", f"{NOWHERE}/x.lua"), "x.lua"),
            *bad_files("wireshark", option="--model"),
        ],
        "cases": [
            Bad(("cases", "--only", "["), "--only"),
            Bad(("cases", "--skip", "["), "--skip"),
        ],
        "run": [
            *bad_numbers("run", "--only", "nothing", option="--timeout-scale"),
            Bad(("run", "--repeat", "-1"), "--repeat"),
            Bad(("run", "--repeat", "0"), "--repeat"),
            Bad(("run", "--seed", "nan"), "--seed"),
            *(
                Bad(("run", "--only", "nothing", "--impair", spec), "--impair")
                for spec in ("loss=nan%", "delay=1e9ms", "loss=200%", "garbage", "jitter=infms")
            ),
            *bad_files("run", "--only", "nothing", option="--ics", kinds=NOT_EMPTY),
            Bad(("run", "--ics", "{garbage toml}"), "garbage.toml"),
            Bad(("run", "--ics", json_file(folder, "rsp5.toml", "rsp = 5\n")), "rsp5.toml"),
            *bad_files("run", "--only", "nothing", option="--baseline", kinds=NOT_EMPTY),
            *(
                Bad(("run", "--baseline", json_file(folder, name, text)), name)
                for name, text in baselines.items()
            ),
            Bad(("run", "--baseline", "{garbage json}"), "garbage.json"),
            *(
                Bad(("run", option, target), option)
                for option in ("--target", "--rsp-target")
                for target in ("::::", "", "127.0.0.1:99999", "a b", "127.0.0.1:x")
            ),
            *bad_files("run", "--target", "127.0.0.1:9", option="--rcml"),
            *bad_files("run", "--rsp-target", "127.0.0.1:9", option="--model"),
            Bad(("run", "--only", "nothing", "--junit", f"{NOWHERE}/j.xml"), "j.xml"),
            Bad(("run", "--only", "nothing", "--json", f"{NOWHERE}/j.json"), "j.json"),
            Bad(("run", "--only", "nothing", "--capture", "{empty}/d"), "--capture"),
            Bad(("run", "--only", "["), "--only"),
            *(
                Bad(("run", "--role", "client", "--listen", port), "--listen")
                for port in ("-1", "70000", "x", "::::")
            ),
        ],
        "serve": [
            *bad_files("serve"),
            Bad(("serve", "{huge}"), "huge"),
            *(Bad(("serve", "--port", port, CAMERA), "--port") for port in ("-1", "70000", "x")),
            Bad(("serve", "--ready-file", f"{NOWHERE}/r.json", "--port", "0", CAMERA), "r.json"),
            Bad(("serve", "--driver", "nope", CAMERA), "--driver"),
            Bad(("serve", "--fault", "nope", CAMERA), "--fault"),
        ],
        "robot": [
            *bad_files("robot"),
            *(Bad(("robot", "--port", port, CUBO), "--port") for port in ("-1", "70000", "x")),
            Bad(("robot", "--ready-file", f"{NOWHERE}/r.json", "--port", "0", CUBO), "r.json"),
            *bad_files(
                "robot",
                "--port",
                "0",
                "--encryption",
                "aes-256-gcm",
                option="--psk-file",
                after=(CUBO,),
            ),
            Bad(("robot", "--fault", "nope", CUBO), "--fault"),
        ],
        "local": [
            *bad_files("local", "--robot", "127.0.0.1:9"),
            *bad_numbers(*local, option="--period"),
            Bad((*local, "--period", "0"), "--period"),
            *bad_numbers(*local, option="--duration"),
            Bad((*local, "--watch", "leftWheel"), "leftWheel"),
            Bad((*local, "--watch", "nothing"), "nothing"),
            Bad((*local, "--activate", "nothing"), "nothing"),
            Bad((*local, "--write", "nothing", "speed=1"), "nothing"),
            Bad((*local, "--write", "leftWheel", "nope=1"), "nope"),
            Bad((*local, "--write", "leftWheel", "speed=nan"), "speed"),
            Bad((*local, "--issue", "nothing", "code=1"), "nothing"),
            Bad(("local", CUBO, "--robot", "::::"), "--robot"),
            Bad(("local", CUBO, "--robot", "127.0.0.1:70000"), "--robot"),
        ],
        "client": [
            *(
                Bad(("client", url, "read", "/status/lens"), "URL")
                for url in (
                    "rctp://127.0.0.1:9/%00",
                    "rctp://127.0.0.1:9/rover/../../x",
                    "rctp://127.0.0.1:9/" + "a" * 70_000,
                    "",
                    "http://127.0.0.1:9/camera",
                    "rctp://[::1/x",
                )
            ),
            *(
                Bad(
                    ("client", "--timeout", number, "rctp://127.0.0.1:9/x", "read", "/a"),
                    "--timeout",
                )
                for number in (*NUMBERS, "0")
            ),
            Bad(
                ("client", "--rcml", "http://[::1/x", "rctp://127.0.0.1:9/x", "read", "/a"),
                "--rcml",
            ),
            *bad_files("client", option="--rcml", after=("rctp://127.0.0.1:9/x", "read", "/a")),
            *bad_numbers(*client, "acquire", "/", option="--hold"),
            *bad_numbers(*client, "stream", "/stream/control", option="--duration"),
            *bad_numbers(*client, "watch", option="--duration"),
            Bad((*client, "read", "no-slash"), "no-slash"),
        ],
        "rsp generate": [
            *bad_files("rsp", "generate"),
            Bad(("rsp", "generate", CUBO, "-o", f"{NOWHERE}/x.py"), "x.py"),
        ],
    }


def answer(bad: Bad, made: dict[str, Path]) -> tuple[Bad, subprocess.CompletedProcess[bytes]]:
    args = list(bad.args)
    for kind, path in made.items():
        args = [arg.replace(f"{{{kind}}}", str(path)) for arg in args]
    done = subprocess.run(
        [*COMMAND, *args], capture_output=True, timeout=BOUND, check=False, stdin=subprocess.DEVNULL
    )
    return bad, done


def problems(
    bad: Bad, done: subprocess.CompletedProcess[bytes], made: dict[str, Path], folder: Path
) -> str:
    err = done.stderr.decode("utf-8", "replace")
    printed = err + done.stdout.decode("utf-8", "replace")
    wrong = []
    if done.returncode not in (1, 2):
        wrong.append(f"exit {done.returncode}")
    if "Traceback" in err or "bug in rcmlconf" in err:
        wrong.append("an internal error")
    name = str(made[bad.names].relative_to(folder)) if bad.names in made else bad.names
    # As the console writes it (escaped), as Python quotes it, or its bytes as they are where
    # they are printable.
    raw = name.encode("utf-8", "surrogateescape").decode("utf-8", "replace")
    shown = {printable(name), repr(name)[1:-1], raw}
    if not any(one in line for line in printed.splitlines() for one in shown if "\n" not in one):
        wrong.append(f"no line names {printable(name)!r}")
    return f"{bad.id!r}: {', '.join(wrong)}:\n{err[-600:]}" if wrong else ""


@pytest.mark.parametrize("command", list(sweep(Path("/"))))
def test_bad_input_is_one_located_line(command: str, tmp_path: Path) -> None:
    made = files(tmp_path)
    rows = sweep(tmp_path)[command]
    with ThreadPoolExecutor(4) as pool:
        answers = list(pool.map(lambda bad: answer(bad, made), rows))
    found = [found for bad, done in answers if (found := problems(bad, done, made, tmp_path))]
    assert not found, f"{len(found)} of {len(rows)} answered wrong:\n" + "\n".join(found)
