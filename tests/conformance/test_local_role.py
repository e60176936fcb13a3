"""`rcmlconf run --role local`: the harness plays a robot and tests the RSP local system that
sends to it, one run of the conformance scenario (specs/rsp.md D-RSP-24) a case. Here the local
system is the reference simulacrum driven by the scenario, started again after every run, as a
user's test driver would be."""

from __future__ import annotations

import asyncio
import contextlib
import json
import os
import socket
import subprocess
from pathlib import Path

from support.processes import COMMAND

from rcmlconf.conformance.probes.local_scenario import reference_local
from rcmlconf.conformance.targets import REFERENCE_RMODEL
from rcmlconf.rsp.security import KEY_SIZE
from rcmlconf.validate.validator import load_robot_model

#: The whole run, at most (seconds).
BOUND = 60.0


def free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


def test_role_local_tests_each_run_of_the_local_system_under_test(tmp_path: Path) -> None:
    psk = os.urandom(KEY_SIZE)
    (tmp_path / "cubo.key").write_text(psk.hex())
    ics = tmp_path / "ics.toml"
    ics.write_text('[rsp]\npsk-file = "cubo.key"\n')
    report = tmp_path / "r.json"
    port = free_udp_port()
    args = ["run", "--role", "local", "--listen", str(port), "--model", str(REFERENCE_RMODEL)]
    process = subprocess.Popen(
        [*COMMAND, *args, "--ics", str(ics), "--only", "rsp/local/*", "--json", str(report)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    model = load_robot_model(REFERENCE_RMODEL)

    async def local_systems() -> None:
        loop = asyncio.get_running_loop()
        deadline = loop.time() + BOUND
        while process.poll() is None and loop.time() < deadline:
            with contextlib.suppress(OSError):
                await asyncio.wait_for(reference_local(model, psk, ("127.0.0.1", port)), 15)
            await asyncio.sleep(0.02)  # between runs, as a user's driver would

    try:
        asyncio.run(local_systems())
        out, err = process.communicate(timeout=30)
    finally:
        if process.poll() is None:
            process.kill()
            process.communicate()
    assert process.returncode == 0, out + err
    verdicts = {r["case"]: r["verdict"] for r in json.loads(report.read_text())["results"]}
    assert len(verdicts) >= 12
    assert set(verdicts.values()) == {"pass"}, verdicts


def test_role_local_needs_listen_and_model() -> None:
    model = ["--model", str(REFERENCE_RMODEL)]
    for args, reason in [
        (["--role", "local", *model], "--role local needs --listen"),
        (["--role", "local", "--listen", "7340"], "--role local needs --listen"),
        (["--role", "local", "--listen", "7340", *model, "--rsp-target", "127.0.0.1"], "targets"),
    ]:
        done = subprocess.run([*COMMAND, "run", *args], capture_output=True, text=True, check=False)
        assert done.returncode == 2, (args, done.stderr)
        assert reason in done.stderr, (args, done.stderr)
