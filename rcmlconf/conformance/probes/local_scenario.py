"""The conformance scenario of D-RSP-24 as a local system runs it: its bounds (`SCENARIO_LIFETIME`,
`REQUESTED`), which the cases of local systems judge by, and one run of it by the reference
simulacrum (`reference_local`), the embedded local system that `LocalListener` summons for a case.
"""

from __future__ import annotations

import asyncio

from rcmlconf.conformance.probes.rsp_devices import zero_values
from rcmlconf.conformance.transcript import Address
from rcmlconf.reference.rsp.simulacrum import NoSession, Simulacrum
from rcmlconf.rsp.codec import Encryption, RefusedReason
from rcmlconf.rsp.codec.bodies import MAX_PERIOD_MS
from rcmlconf.rsp.model import Device, DeviceKind, RobotModel
from rcmlconf.rsp.session import events

#: D-RSP-24 step 5: a run ends this long after WELCOME at the latest.
SCENARIO_LIFETIME = 10.0
#: The kinds the scenario requests (step 2) and stops requesting (step 4).
REQUESTED = (DeviceKind.SENSOR, DeviceKind.MONITOR, DeviceKind.EVENT, DeviceKind.MEMORY_EVENT)


def first_of(model: RobotModel, kind: DeviceKind) -> Device | None:
    return next((d for d in model.devices if d.kind is kind), None)


async def reference_local(model: RobotModel, psk: bytes | None, robot: Address) -> None:
    """One run of D-RSP-24's scenario by the reference simulacrum against the robot at `robot`:
    unencrypted first, then each AEAD while the robot refuses with reason 2 and `psk` is known."""
    ladder = [Encryption.NONE]
    if psk is not None:
        ladder += [Encryption.AES_256_GCM, Encryption.CHACHA20_POLY1305]
    for encryption in ladder:
        key = psk if encryption is not Encryption.NONE else None
        simulacrum = Simulacrum(model, robot, encryption=encryption, psk=key)
        try:
            opened = await simulacrum.open()
        except NoSession:
            refused = simulacrum.closed
            if (
                isinstance(refused, events.SessionRefused)
                and refused.reason is RefusedReason.ENCRYPTION_NOT_OFFERED
            ):
                continue
            return
        try:
            await _use(simulacrum, opened.period)
        finally:
            await simulacrum.aclose()
        return


async def _use(simulacrum: Simulacrum, period: float) -> None:
    """Steps 2 to 5 of D-RSP-24 on an open session."""
    model = simulacrum.model
    for device in model.devices:
        if device.kind is DeviceKind.EFFECTOR:
            simulacrum.write(device.name, zero_values(device))
        elif device.kind is DeviceKind.MODULE or device.kind in REQUESTED:
            simulacrum.set_active(device.name, True)
    command = first_of(model, DeviceKind.COMMAND)
    memory = first_of(model, DeviceKind.MEMORY_COMMAND)
    if command is not None:
        simulacrum.issue(command.name, zero_values(command))
    if memory is not None:
        for _ in range(model.command_buffers + 1):
            simulacrum.issue(memory.name, zero_values(memory))
    in_force = [period]

    def echo(_: object) -> None:
        if command is not None:
            simulacrum.issue(command.name, zero_values(command))

    def idle(_: object) -> None:
        for device in model.devices:
            if device.kind in (DeviceKind.MODULE, DeviceKind.EFFECTOR, *REQUESTED):
                simulacrum.set_active(device.name, False)
        in_force[0] = min(2 * in_force[0], MAX_PERIOD_MS / 1000)
        simulacrum.set_period(in_force[0])

    for device in model.devices:
        if device.kind is DeviceKind.EVENT:
            simulacrum.listen(device.name, echo)
        elif device.kind is DeviceKind.MEMORY_EVENT:
            simulacrum.listen(device.name, idle)
    loop = asyncio.get_running_loop()
    deadline = loop.time() + SCENARIO_LIFETIME
    while simulacrum.closed is None and loop.time() < deadline:
        await asyncio.sleep(0.01)
