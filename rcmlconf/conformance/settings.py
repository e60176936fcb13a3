"""The settings of a run, as `rcmlconf run` reads them from its options.

`TargetSettings` says what is tested and how the harness reaches it. Any command that tests a
target can take the same options through it. `RunSettings` adds what to run and what to write.

Each field is named after its option: `rsp_target` is --rsp-target.
The module is light: `rcmlconf run` builds the settings before it imports the harness.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Literal

if TYPE_CHECKING:
    from rcmlconf.conformance.targets import Address

#: --role: the role of the implementation under test.
RoleName = Literal["server", "client", "local"]


@dataclass(frozen=True, slots=True, kw_only=True)
class TargetSettings:
    """What is tested, and how the harness reaches it. No target at all: the embedded
    reference."""

    #: --target: an RCTP server.
    target: Address | None
    #: --rcml: the RCML file of --target's robot, or of the robot a tested client sees.
    rcml: Path | None
    #: --site: --target's site path.
    site: str | None
    #: --rsp-target: an RSP robot.
    rsp_target: Address | None
    #: --model: the robot model of --rsp-target, or of the robot the harness plays.
    model: Path | None
    #: --ics: the target's implementation conformance statement.
    ics: Path | None
    #: --role.
    role: RoleName
    #: --listen: where a tested client or local system connects or sends.
    listen: Address | None
    #: --client-command: starts the tested client or local system for each case.
    client_command: str | None
    #: --connect-timeout: how long a case waits for its client or local system, in seconds.
    connect_timeout: float
    #: --fault: the names of the faults the embedded reference has.
    faults: tuple[str, ...]


@dataclass(frozen=True, slots=True, kw_only=True)
class ReportFiles:
    """Where the run's reports go. None: that report is not written."""

    #: --junit.
    junit: Path | None
    #: --json.
    json: Path | None
    #: --html.
    html: Path | None


@dataclass(frozen=True, slots=True, kw_only=True)
class RunSettings:
    """Everything `rcmlconf run` is told."""

    tested: TargetSettings
    reports: ReportFiles
    #: --list: list the chosen cases and run none.
    list_only: bool
    #: --strict: an inconclusive case fails the run.
    strict: bool
    #: --only and --skip: globs of case IDs.
    only: tuple[str, ...]
    skip: tuple[str, ...]
    #: --repeat: how many times each case runs.
    repeat: int
    #: --verify: how many times each case runs to judge it stable. None: no judgement.
    verify: int | None
    #: --timeout-scale: multiplies every case's timeout.
    timeout_scale: float
    #: --session-wait: the longest session timeout (D-RCTP-11) that the cases wait out.
    session_wait: float
    #: --seed: seeds every impairment.
    seed: int
    #: --impair: the impairment spec of the cases that declare none, as given.
    impair: str | None
    #: --concurrency: how many cases are in flight at once.
    concurrency: int
    #: --baseline: the known failures.
    baseline: Path | None
    #: --capture: the directory for a pcap of each case.
    capture: Path | None
    #: --verbose: a line for every case, passes too.
    verbose: bool

    @property
    def runs(self) -> int:
        """How many times each case runs: --verify's N, else --repeat."""
        return self.verify or self.repeat
