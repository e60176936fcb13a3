"""`rcmlconf fuzz` once click has read its options: reach the target, run the campaign, write
the reports, exit with the campaign's status."""

from __future__ import annotations

import os
import sys
import tempfile
import time
from pathlib import Path
from typing import Any, NoReturn

from rcmlconf.cli.console import Output
from rcmlconf.cli.run_target import fetched_robot
from rcmlconf.conformance.probes.clients import HARNESS_RCML
from rcmlconf.conformance.settings import TargetSettings
from rcmlconf.conformance.targets import REFERENCE_RCML
from rcmlconf.fuzz.campaign import Budget, Stats
from rcmlconf.fuzz.findings import FindingFileError
from rcmlconf.fuzz.launch import (
    ANSWER_WAIT,
    Reached,
    campaign_for,
    embedded_command,
    finish,
    free_pair,
    free_port,
    played_robot,
    reference_client,
    reference_local,
    replay,
    resume_state,
    started,
    subject_for,
    write_reports,
)
from rcmlconf.fuzz.monitor import LeakWatch, TargetCommandError, TargetNotReady
from rcmlconf.validate.validator import load_robot, load_robot_model

#: Without a terminal, a progress line this often (seconds).
QUIET_TICK = 5.0
DEFAULT_SECONDS = 60.0
#: --max-rate's default off loopback (D-FUZZ-7).
REMOTE_RATE = 200.0


def _fail(output: Output, text: str, status: int = 2) -> NoReturn:
    output.problem("fuzz", text)
    sys.exit(status)


def _listen_failed(output: Output, address: tuple[str, int], error: OSError) -> NoReturn:
    reason = os.strerror(error.errno) if error.errno else str(error)
    _fail(output, f"cannot listen on {address[0]}:{address[1]} (--listen): {reason}")


def _reach(
    output: Output, tested: TargetSettings, options: dict[str, Any]
) -> tuple[Reached, str | None, float]:
    """The target, the command that starts it (None: it runs already) and the answer wait."""
    command = options.pop("target_command")
    wait = ANSWER_WAIT * options.pop("timeout_scale")
    if tested.role == "client":
        return _played(output, tested, command, wait)
    if tested.role == "local":
        return _played_robot(output, tested, command, wait)
    given = tested.target or tested.rsp_target
    if given is not None and tested.faults:
        _fail(output, "--fault is for the embedded reference: leave out --target")
    if given is None and command is not None:
        _fail(output, "--target-command needs --target or --rsp-target: the address it listens on")
    if tested.rsp_target is not None or (given is None and tested.model is not None):
        if tested.model is None:
            _fail(output, "--rsp-target needs --model: the robot's model")
        model = load_robot_model(tested.model)
        if given is None:
            address = ("127.0.0.1", free_port())
            command = embedded_command(address[1], tested.faults, tested.model)
            described: dict[str, Any] = {"embedded": True, "model": str(tested.model)}
        else:
            address = (given[0], given[1])
            described = {"address": f"{address[0]}:{address[1]}", "command": command}
        described["role"] = "robot"
        return Reached(address=address, model=model, described=described), command, wait
    if given is None:
        address = ("127.0.0.1", free_port())
        command = embedded_command(address[1], tested.faults)
        robot = load_robot(REFERENCE_RCML)
        described = {"embedded": True, "faults": list(tested.faults)}
    else:
        address = (given[0], given[1])
        if tested.rcml is not None:
            robot = load_robot(tested.rcml)
        elif command is None:
            robot = fetched_robot(output, given, wait)
        else:
            _fail(output, "--target-command needs --rcml: the server is not up to ask")
        described = {"address": f"{address[0]}:{address[1]}", "command": command}
    site = tested.site or robot.site.path or "/"
    described |= {"role": "server", "site": site}
    return Reached(address=address, robot=robot, site=site, described=described), command, wait


def _per_case_command(
    output: Output, tested: TargetSettings, command: str | None, embedded: str, where: str
) -> str:
    """--client-command, which starts the implementation under test for each case (`embedded`,
    the reference's, without it); --target-command has no place beside it."""
    if command is not None:
        _fail(output, f"--target-command starts a server or a robot; with --role {tested.role}"
              " give --client-command 'CMD {url}'")  # fmt: skip
    started = tested.client_command or embedded
    if "{url}" not in started:
        _fail(output, f"--client-command needs {{url}}: where the {where}")
    return started


def _described(tested: TargetSettings, listen: tuple[str, int], started: str) -> dict[str, Any]:
    """What the reports say a target started for each case is."""
    return {
        "role": tested.role,
        "listen": f"{listen[0]}:{listen[1]}",
        "command": started,
        "embedded": tested.client_command is None,
    }


def _played(
    output: Output, tested: TargetSettings, command: str | None, wait: float
) -> tuple[Reached, str | None, float]:
    """--role client (D-FUZZ-8): the fuzzer plays the harness's robot at --listen to the
    client --client-command starts for each case (the embedded reference client without it)."""
    client = _per_case_command(output, tested, command, reference_client(), "client is to connect")
    listen = tested.listen or ("127.0.0.1", free_pair())
    folder = Path(tempfile.mkdtemp(prefix="rcmlconf-fuzz-"))
    robot_file = played_robot(tested.rcml or HARNESS_RCML, listen, folder)
    robot = load_robot(robot_file)
    reached = Reached(
        address=(listen[0], listen[1]),
        robot=robot,
        described=_described(tested, listen, client),
        client_command=client,
        played=robot_file,
        connect_timeout=tested.connect_timeout,
    )
    return reached, None, wait


def _played_robot(
    output: Output, tested: TargetSettings, command: str | None, wait: float
) -> tuple[Reached, str | None, float]:
    """--role local (D-FUZZ-9): the fuzzer plays a robot of --model at --listen to the local
    system --client-command starts for each case (the embedded reference's without it)."""
    if tested.model is None:
        _fail(output, "--role local needs --model: the robot the fuzzer plays")
    local = _per_case_command(
        output, tested, command, reference_local(tested.model), "local system is to send"
    )
    listen = tested.listen or ("127.0.0.1", free_port())
    model = load_robot_model(tested.model)
    reached = Reached(
        address=(listen[0], listen[1]),
        model=model,
        described={**_described(tested, listen, local), "model": str(tested.model)},
        client_command=local,
        connect_timeout=tested.connect_timeout,
    )
    return reached, None, wait


def fuzz_target(tested: TargetSettings, options: dict[str, Any]) -> None:
    output = Output()
    reached, command, wait = _reach(output, tested, options)
    address = reached.address
    out: Path = options.pop("resume") or options.pop("out")
    out.mkdir(parents=True, exist_ok=True)
    loopback = address[0] in ("127.0.0.1", "::1", "localhost")
    rate = options.pop("max_rate") or (None if loopback else REMOTE_RATE)
    seconds, cases = options.pop("seconds"), options.pop("cases")
    budget = Budget(
        seconds=seconds if seconds is not None or cases is not None else DEFAULT_SECONDS,
        cases=cases,
        max_rate=rate,
        max_memory=options.pop("max_memory"),
    )
    leaks = LeakWatch(rss_limit=options.pop("leak_rss") * 2**20, fd_limit=options.pop("leak_fds"))
    #: --state and --kind: where the campaign puts its effort (empty: everywhere).
    focus: dict[str, tuple[str, ...]] = {
        "states": options.pop("state"),
        "kinds": options.pop("kind"),
    }
    try:
        state = resume_state(out)
    except ValueError as error:
        _fail(output, str(error))
    try:
        with started(command, address, wait, reached.transport) as process:
            try:
                campaign, subject = campaign_for(
                    reached,
                    process=process,
                    out=out,
                    seed=options["seed"],
                    budget=budget,
                    wait=wait,
                    leaks=leaks,
                    progress=progress_for(output),
                    only=focus["states"],
                    only_kinds=focus["kinds"],
                )
            except ValueError as error:
                _fail(output, str(error))
            except OSError as error:  # the played side's port (--role client or local)
                _listen_failed(output, address, error)
            problem = subject.alive()
            if problem is not None:
                _fail(output, f"{address[0]}:{address[1]}: {problem.text}")
            if state is not None:
                campaign.resume(state)
                output.notice(f"resuming {out}: {campaign.stats.cases} cases run before")
            try:
                campaign.run()
            except KeyboardInterrupt:
                campaign.stopped = "interrupted"
            finally:
                subject.close()
            settings = {"seed": options["seed"], "target": reached.described}
            document = finish(campaign, {**settings, **{k: list(v) for k, v in focus.items()}})
    except (TargetNotReady, TargetCommandError) as error:
        _fail(output, str(error))
    write_reports(document, options["json_file"], options["junit"])
    _summary(output, document, out)


def _summary(output: Output, document: dict[str, Any], out: Path) -> NoReturn:
    for item in document["findings"]:
        output.live(
            [
                (f"{out / item['file']}: ", "bold"),
                (f"{item['oracle']} ", "bold red"),
                (f"[{item['requirement']}] in {item['state']}: {item['text']}", ""),
                (f" (fired {item['count']}, stable {item['stable']})", "dim"),
            ]
        )
    if document["stopped"]:
        output.notice(f"stopped: {document['stopped']}")
    found = len(document["findings"])
    output.summary(
        f"{document['cases']} cases in {document['seconds']:.1f} s"
        f" ({document['cases_per_second']:.0f}/s), {document['states_reached']} states reached,"
        f" {found} finding{'s' if found != 1 else ''}; report: {out / 'report.json'}",
        found == 0,
    )
    sys.exit(1 if found else 0)


def replay_finding(path: Path, tested: TargetSettings, options: dict[str, Any]) -> NoReturn:
    output = Output()
    reached, command, wait = _reach(output, tested, options)
    try:
        with started(command, reached.address, wait, reached.transport) as process:
            try:
                subject = subject_for(reached, wait)
            except OSError as error:  # the played side's port (--role client or local)
                _listen_failed(output, reached.address, error)
            try:
                verdict = replay(path, subject, process)
            except FindingFileError as error:
                _fail(output, str(error))
            finally:
                subject.close()
    except (TargetNotReady, TargetCommandError) as error:
        _fail(output, str(error))
    if verdict is None:
        output.summary(f"{path}: did not reproduce", True)
        sys.exit(0)
    output.summary(f"{path}: reproduced: {verdict.oracle} [{verdict.rule}] {verdict.text}", False)
    sys.exit(1)


def tick(output: Output, every: float) -> Any:
    """The progress callback: a line each `every` seconds."""
    last = [0.0]

    def show(stats: Stats) -> None:
        now = time.monotonic()
        if now - last[0] < every:
            return
        last[0] = now
        output.notice(
            f"{stats.cases} cases, {stats.rate:.0f}/s, {stats.states} states reached,"
            f" {stats.findings} findings ({stats.fired} fired), {stats.restarts} restarts"
        )

    return show


def progress_for(output: Output) -> Any:
    return tick(output, 1.0 if sys.stderr.isatty() else QUIET_TICK)
