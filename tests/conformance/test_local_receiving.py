"""What an RSP local system does with what it receives (rcmlconf.conformance.cases.rsp_local.
receiving): the cases pass the embedded reference's local system and an independent one
(tests/foreign/rsp_local, written from specs/ alone), and each fails that independent one when it
is told to make the fault the case is aimed at, naming the requirement the fault breaks (and so do
the cases of its header, of taking events per device and of resending, rsp_local's header,
session and sending modules, aimed at faults of the same system). A local
system that goes on with its session after the robot's BYE fails rsp/local/bye-ends, and the case
after it still has a session of its own (`LocalListener.settled`), where it had been inconclusive
("no local system sent a HELLO"). Real processes on loopback: `rcmlconf run --role local` and the
independent local system's `main.py --loop`; and, in this process, what the probe forges in an
encrypted session, read by the reference local system."""

from __future__ import annotations

import asyncio
import json
import os
import socket
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
from support.mutants import mutated
from support.processes import COMMAND, free_port

from rcmlconf.conformance.cases.rsp_local.session import occurrence
from rcmlconf.conformance.probes.local_listener import LocalListener
from rcmlconf.conformance.probes.rsp_datagram import Datagram
from rcmlconf.conformance.probes.rsp_devices import first
from rcmlconf.conformance.targets import REFERENCE_RMODEL
from rcmlconf.conformance.transcript import Transcript
from rcmlconf.reference.rsp.simulacrum import Simulacrum
from rcmlconf.rsp.codec import Encryption, MapBody, PacketType
from rcmlconf.rsp.model import DeviceKind
from rcmlconf.rsp.security import KEY_SIZE
from rcmlconf.rsp.session import events
from rcmlconf.validate.validator import load_robot_model

FOREIGN = Path(__file__).parents[1] / "foreign" / "rsp_local"
MODEL = FOREIGN / "robot.rmodel"
#: The fault of the independent local system each case is aimed at, and what it must fail with.
AIMED = {
    "rsp/local/other-session-dropped": ("no-session-check", "R-RSP-18"),
    "rsp/local/trailing-bytes-dropped": ("trailing-bytes", "R-RSP-18"),
    "rsp/local/bad-bool-dropped": ("bool-lenient", "R-RCML-30"),
    "rsp/local/replay-dropped": ("no-replay-list", "R-RSP-18"),
    "rsp/local/outside-window-dropped": ("window-65", "R-RSP-18"),
    "rsp/local/late-buffer-ignored": ("late-states", "R-RSP-19"),
    "rsp/local/ack-at-once": ("ack-deferred", "R-RSP-26"),
    # Its header, how it takes occurrences and resends, as it receives the robot's packets:
    "rsp/local/stamps-since-first-hello": ("timestamp-from-welcome", "R-RSP-14"),
    "rsp/local/last-received-ack": ("lastrecv-uplink-only", "R-RSP-15"),
    "rsp/local/events-taken-per-device": ("taken-per-kind", "R-RSP-25"),
    "rsp/local/memory-command-resent": ("rto-no-ceiling", "R-RSP-28"),
}
#: Cases no fault of the independent local system is aimed at: each fails the embedded
#: reference made to make its fault in a copy (`mutated`).
UNAIMED = ["rsp/local/downlink-dropped"]
#: A run, at most (seconds): the BYE test waits out a session that goes on for 10 s.
BOUND = 60.0

Results = dict[str, dict[str, Any]]


def run(tmp_path: Path, *options: str, python: Path | None = None) -> Results:
    """`rcmlconf run OPTIONS --json`: each result by case; the package copied into `python`
    (`mutated`) instead of the installed one if given."""
    report = tmp_path / "run.json"
    copied = [sys.executable, "-m", "rcmlconf"] if python is not None else COMMAND
    env = {**os.environ, "PYTHONPATH": str(python)} if python is not None else None
    done = subprocess.run(
        [*copied, "run", *options, "--json", str(report)],
        capture_output=True,
        text=True,
        timeout=BOUND,
        check=False,
        cwd=python,
        env=env,
    )
    assert "Traceback" not in done.stderr, done.stderr
    # Exit 2 is also "nothing was tested": every case inconclusive (a loaded machine held the
    # harness's loop, say). The callers judge those; a usage error writes no report.
    assert done.returncode in (0, 1, 2), done.stdout + done.stderr
    assert report.exists(), done.stdout + done.stderr
    results = {r["case"]: r for r in json.loads(report.read_text())["results"]}
    if done.returncode == 2:
        verdicts = {r["verdict"] for r in results.values()}
        assert verdicts <= {"inconclusive", "not applicable"}, done.stdout + done.stderr
    return results


def run_foreign(tmp_path: Path, cases: list[str], *faults: str) -> Results:
    """The cases against the independent local system making `faults`, run after run."""
    port = free_port(socket.SOCK_DGRAM)
    wrong = [option for fault in faults for option in ("--fault", fault)]
    robot = ["--robot", f"127.0.0.1:{port}", "--model", str(MODEL)]
    local = subprocess.Popen(
        [sys.executable, str(FOREIGN / "main.py"), *robot, "--loop", *wrong],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        only = [option for case in cases for option in ("--only", case)]
        return run(tmp_path, "--role", "local", "--listen", str(port), "--model", str(MODEL), *only)
    finally:
        local.terminate()  # it ends its session with BYE and exits 0
        _, err = local.communicate(timeout=BOUND)
        assert local.returncode == 0, err


def verdicts(results: Results) -> dict[str, str]:
    return {case: result["verdict"] for case, result in results.items()}


def test_the_receiving_cases_pass_the_embedded_reference(tmp_path: Path) -> None:
    cases = [*AIMED, *UNAIMED]
    results = run(tmp_path, *(option for case in cases for option in ("--only", case)))
    assert verdicts(results) == dict.fromkeys(cases, "pass"), results


def test_the_receiving_cases_pass_an_independent_local_system(tmp_path: Path) -> None:
    cases = [*AIMED, *UNAIMED]
    results = run_foreign(tmp_path, cases)
    assert verdicts(results) == dict.fromkeys(cases, "pass"), results


@pytest.mark.parametrize("case", AIMED)
def test_each_case_fails_the_local_system_making_its_fault(tmp_path: Path, case: str) -> None:
    fault, requirement = AIMED[case]
    result = run_foreign(tmp_path, [case], fault)[case]
    assert (result["verdict"], result["requirement"]) == ("fail", requirement), result


def test_a_local_system_taking_a_downlink_as_an_ack_fails_downlink_dropped(tmp_path: Path) -> None:
    """The embedded reference, in a copy, reading a DOWNLINK from the robot as an ACK (a type it
    is not sent, D-RSP-11: bench/mutation_survivors.md's local.py 269): the DOWNLINK naming its
    command in flight ends the command's ride."""
    copy = mutated(
        tmp_path,
        "rsp/session/local.py",
        ("elif kind is PacketType.ACK:", "elif kind in (PacketType.ACK, PacketType.DOWNLINK):"),
        ('drop_unsent(data, SENT_TO_LOCAL, "the local system")', "pass"),
    )
    case = "rsp/local/downlink-dropped"
    result = run(tmp_path, "--only", case, python=copy)[case]
    assert (result["verdict"], result["requirement"]) == ("fail", "R-RSP-18"), result


def test_a_session_going_on_after_bye_fails_bye_ends_and_the_next_case_has_its_own(
    tmp_path: Path,
) -> None:
    cases = ["rsp/local/bye-ends", "rsp/local/every-period"]  # run in this order (by ID)
    results = run_foreign(tmp_path, cases, "bye-ignored")
    bye, after = (results[case] for case in cases)
    assert (bye["verdict"], bye["requirement"]) == ("fail", "R-RSP-22"), bye
    assert after["verdict"] == "pass", after


async def forged_in_a_sealed_session() -> tuple[list[events.PacketDropped], Datagram | None]:
    """The reference local system in an AES-256-GCM session with a probe that forges an UPLINK
    with a byte after its payloads, then one naming another session, then sends it well-formed:
    what the reference dropped, and its ACK of the well-formed one."""
    model = load_robot_model(REFERENCE_RMODEL)
    psk = os.urandom(KEY_SIZE)
    listener = LocalListener(model, psk)
    await listener.start("127.0.0.1", 0)
    local = Simulacrum(model, listener.address, encryption=Encryption.AES_256_GCM, psk=psk)
    opening = asyncio.ensure_future(local.open())
    try:
        probe = await listener.accept(Transcript(), 5.0)
        probe.welcome()
        await asyncio.wait_for(opening, 5.0)
        memory = first(model, DeviceKind.MEMORY_EVENT)
        body = MapBody((occurrence(memory, 0),))
        probe.forged(PacketType.UPLINK, body, "longer", alter=lambda plain: plain + b"\x00")
        probe.forged(PacketType.UPLINK, body, "elsewhere", session_id=probe.session_id ^ 1 or 2)
        probe.uplink(body.items)
        ack = await probe.next(PacketType.ACK, wait=5.0)
    finally:
        opening.cancel()
        await local.aclose()
        await listener.close()
    return [e for e in local.history if isinstance(e, events.PacketDropped)], ack


def test_what_is_forged_in_a_sealed_session_authenticates_and_is_dropped_for_its_fault() -> None:
    dropped, ack = asyncio.run(forged_in_a_sealed_session())
    assert [(e.rule, e.reason) for e in dropped] == [
        ("R-RSP-16", "1 bytes after the last payload"),
        ("R-RSP-18", "a packet of another session"),
    ]
    assert ack is not None
