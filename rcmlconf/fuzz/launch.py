"""From `rcmlconf fuzz`'s settings to a running campaign: the robot, the target (started here
under --target-command, or the embedded reference), the subject, and what is written at the end.
"""

from __future__ import annotations

import json
import re
import shlex
import socket
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rcmlconf.conformance.targets import REFERENCE_RCML
from rcmlconf.fuzz.campaign import Budget, Campaign, Cases, Stats, Subject
from rcmlconf.fuzz.client_cases import ClientCases
from rcmlconf.fuzz.client_target import CASE_PATH, ClientTarget
from rcmlconf.fuzz.findings import load_finding
from rcmlconf.fuzz.local_cases import LocalCases
from rcmlconf.fuzz.local_target import LocalTarget
from rcmlconf.fuzz.monitor import LeakWatch, TargetProcess
from rcmlconf.fuzz.oracles import CRASH, HANG, Verdict
from rcmlconf.fuzz.rctp_cases import RctpCases
from rcmlconf.fuzz.rctp_robot import robot_paths
from rcmlconf.fuzz.rctp_target import RctpTarget
from rcmlconf.fuzz.report import report, write_json, write_junit
from rcmlconf.fuzz.rsp_cases import RspCases
from rcmlconf.fuzz.rsp_target import RspTarget
from rcmlconf.fuzz.seeds import control_seeds, rsp_seeds
from rcmlconf.rcml.model import RcmlDocument
from rcmlconf.rsp.model import RobotModel

Address = tuple[str, int]
#: D-FUZZ-4: the bound on every answer, and on a liveness probe's, before --timeout-scale.
ANSWER_WAIT = 5.0


@dataclass(frozen=True, slots=True, kw_only=True)
class Reached:
    """The target of a campaign: an RCTP/2.0 server and its robot's RCML, or an RSP robot and
    its model."""

    address: Address
    robot: RcmlDocument | None = None
    site: str = "/"
    model: RobotModel | None = None
    #: What the reports say the target is.
    described: dict[str, Any]
    #: --role client (D-FUZZ-8) and local (D-FUZZ-9): the command that starts the client or
    #: local system for each case, the played robot's RCML as served (a client's), and how long
    #: a case waits for it to connect.
    client_command: str | None = None
    played: Path | None = None
    connect_timeout: float = 10.0

    @property
    def transport(self) -> str:
        return "udp" if self.model is not None else "tcp"


def embedded_command(port: int, faults: tuple[str, ...], model: Path | None = None) -> str:
    """The reference server (or, given a robot model, the reference robot) as a process of its
    own, so a crash of it is seen as one."""
    if model is not None:
        words = [sys.executable, "-m", "rcmlconf", "robot", str(model), "--port", str(port)]
    else:
        words = [sys.executable, "-m", "rcmlconf", "serve", str(REFERENCE_RCML), "--port"]
        words += [str(port), "--no-http"]
    return shlex.join(words + [f"--fault={name}" for name in faults])


def free_port(host: str = "127.0.0.1") -> int:
    with socket.socket() as probe:
        probe.bind((host, 0))
        port: int = probe.getsockname()[1]
        return port


def free_pair(host: str = "127.0.0.1") -> int:
    """A port P free on TCP and UDP whose P + 1 is free on TCP: a played server's RCTP, data
    stream and files (D-RCTP-29)."""
    for _ in range(100):
        port = free_port(host)
        if port >= 65535:
            continue
        try:
            with socket.socket() as tcp, socket.socket(type=socket.SOCK_DGRAM) as udp:
                tcp.bind((host, port + 1))
                udp.bind((host, port))
        except OSError:
            continue
        return port
    raise OSError(f"no two free ports in a row on {host}")


@contextmanager
def started(
    command: str | None, address: Address, wait: float, transport: str = "tcp"
) -> Iterator[TargetProcess | None]:
    """The target's process under --target-command (None without it), stopped at the end."""
    if command is None:
        yield None
        return
    process = TargetProcess(command, ready=(address[0], address[1], transport), ready_timeout=wait)
    process.start()
    try:
        yield process
    finally:
        process.stop()


def reference_client() -> str:
    """The embedded reference client, as a process of its own: `{url}` is the case URL."""
    return shlex.join([sys.executable, "-m", "rcmlconf", "client", "{url}", "scenario"])


def reference_local(model: Path) -> str:
    """The embedded reference local system running D-RSP-24's scenario, as a process of its
    own: `{url}` is the played robot's address."""
    words = [sys.executable, "-m", "rcmlconf", "local", str(model), "--robot", "{url}"]
    return shlex.join([*words, "--scenario"])


def played_robot(harness: Path, listen: Address, folder: Path) -> Path:
    """The robot the fuzzer plays to a client (D-RCTP-31's harness robot), its `site` the case
    URL of `client_target.CASE_PATH`, written into `folder` as it is served."""
    text = harness.read_text(encoding="utf-8")
    site = f'site="rctp://{listen[0]}:{listen[1]}{CASE_PATH}"'
    text = re.sub(r'\bsite="[^"]*"', site, text, count=1)
    path = folder / harness.name
    path.write_text(text, encoding="utf-8")
    return path


def subject_for(reached: Reached, wait: float) -> Subject:
    if reached.client_command is not None and reached.model is not None:
        return LocalTarget(
            reached.model,
            reached.address,
            reached.client_command,
            wait=wait,
            connect_timeout=reached.connect_timeout,
        )
    if reached.client_command is not None:
        assert reached.robot is not None
        assert reached.played is not None
        return ClientTarget(
            reached.played,
            reached.robot,
            reached.address,
            reached.client_command,
            wait=wait,
            connect_timeout=reached.connect_timeout,
        )
    if reached.model is not None:
        return RspTarget(reached.address, reached.model, wait)
    assert reached.robot is not None
    return RctpTarget(reached.address, reached.robot, reached.site, wait)


def campaign_for(
    reached: Reached,
    *,
    process: TargetProcess | None,
    out: Path,
    seed: int,
    budget: Budget,
    wait: float,
    leaks: LeakWatch | None,
    progress: Callable[[Stats], None],
    only: tuple[str, ...] = (),
    only_kinds: tuple[str, ...] = (),
) -> tuple[Campaign, Subject]:
    """The campaign and its subject. Raises ValueError, before anything starts, for a state in
    `only` (--state) the target has not, or a kind in `only_kinds` (--kind) none of them has."""
    cases: Cases
    if reached.client_command is not None and reached.model is not None:
        cases = LocalCases(reached.model, rsp_seeds(reached.model.model_id))
    elif reached.client_command is not None:
        assert reached.robot is not None
        cases = ClientCases(robot_paths(reached.robot))
    elif reached.model is not None:
        cases = RspCases(reached.model, rsp_seeds(reached.model.model_id))
    else:
        assert reached.robot is not None
        cases = RctpCases(robot_paths(reached.robot, reached.site), control_seeds())
    unknown = [state for state in only if state not in cases.states]
    if unknown:
        states = ", ".join(cases.states)
        raise ValueError(f"--state {unknown[0]!r}: this target's states are {states}")
    kinds = {kind for state in only or cases.states for kind in cases.kinds(state)}
    strange = [kind for kind in only_kinds if kind not in kinds]
    if strange:
        shown = ", ".join(sorted(kinds))
        raise ValueError(f"--kind {strange[0]!r}: the kinds of those states are {shown}")
    subject = subject_for(reached, wait)
    campaign = Campaign(
        subject,
        cases,
        out,
        seed,
        budget,
        reached.described,
        process=process,
        leaks=leaks if process is not None else None,
        progress=progress,
        only=only,
        only_kinds=only_kinds,
    )
    return campaign, subject


def resume_state(out: Path) -> dict[str, Any] | None:
    """The state.json of an earlier campaign in `out`, or None."""
    path = out / "state.json"
    if not path.is_file():
        return None
    item: dict[str, Any] = json.loads(path.read_text(encoding="utf-8"))
    if item.get("schema") != "rcmlconf-fuzz-state/1":
        raise ValueError(f"{path} is not a campaign's state")
    return item


def finish(campaign: Campaign, settings: dict[str, Any]) -> dict[str, Any]:
    """Write the state, the state map and the report into the campaign's folder."""
    campaign.save()
    campaign.map.write(campaign.out, campaign.cases.states)
    document = report(
        campaign.stats,
        sorted(campaign.findings.values(), key=lambda f: f.number),
        campaign.map,
        settings,
        campaign.stopped,
    )
    write_json(campaign.out / "report.json", document)
    return document


def write_reports(document: dict[str, Any], json_file: Path | None, junit: Path | None) -> None:
    if json_file is not None:
        write_json(json_file, document)
    if junit is not None:
        write_junit(junit, document)


def replay(path: Path, subject: Subject, process: TargetProcess | None) -> Verdict | None:
    """Send a finding's case again: the verdict it gets now (None: it did not reproduce)."""
    case, _ = load_finding(path)
    out = subject.run(case)
    found = subject.judge(out) or subject.alive()
    if process is not None and (exit := process.exited()) is not None:
        rule = "R-RCTP-5" if subject.role == "server" else "R-RSP-20"
        return Verdict(CRASH, rule, f"the target's process {exit.text()}")
    if found is not None and found.oracle in (CRASH, HANG, "violation"):
        return found
    return None
