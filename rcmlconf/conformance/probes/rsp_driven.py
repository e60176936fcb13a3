"""An effector driven through the core's endpoint and read back through its monitor (`drive`,
`Driven`): what a monitor reports of the value written (R-RSP-34)."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass

from rcmlconf.conformance.context import Context
from rcmlconf.conformance.probes.awaited import must_come
from rcmlconf.conformance.probes.rsp_devices import close_to, modules_of, monitored, visible
from rcmlconf.conformance.probes.rsp_probe import RspProbe, open_probe
from rcmlconf.conformance.verdicts import Inconclusive
from rcmlconf.rsp.model import Device, Field
from rcmlconf.rsp.session import events
from rcmlconf.values import Value


@dataclass(frozen=True, slots=True)
class Driven:
    """An effector the session's endpoint writes a value to, with every module it needs active
    and its monitor requested (`drive`): what the monitor reports of it (R-RSP-34)."""

    probe: RspProbe
    opened: events.SessionOpened
    effector: Device
    monitor: Device
    #: The value written: each field well away from 0 (`visible`).
    wanted: dict[str, Value]

    @property
    def field(self) -> Field:
        """The field the monitor is read by."""
        return self.effector.fields[0]

    def at_wanted(self, values: Mapping[str, Value]) -> bool:
        """Whether a report of the monitor has the value written."""
        return close_to(self.field, values.get(self.field.name), self.wanted[self.field.name])

    async def reached(self) -> bool:
        """Whether the monitor reports the value written within the probe's wait."""
        return await self.probe.state(self.monitor.name, self.at_wanted) is not None

    async def shown(self, ctx: Context, requirement: str) -> None:
        """The monitor reporting the value written, which must come within the probe's wait
        (`must_come`: a robot, or a harness, short of CPU may miss it; `requirement` fails)."""
        since = self.probe.now
        await must_come(
            ctx,
            self.probe,
            lambda wait: self.probe.state(
                self.monitor.name, self.at_wanted, wait=wait, since=since
            ),
            self.probe.wait,
            f"{self.monitor.name} reporting {self.wanted} (D-RSP-27: its effector's actual"
            " state, as far as the body has carried out the value applied)",
            requirement,
            instead=lambda: f"its newest report {self.latest()}",
        )

    async def settled(self) -> None:
        """The monitor reporting the value written; Inconclusive if it never does (a case about
        what follows has nothing to start from)."""
        if not await self.reached():
            raise Inconclusive(f"{self.monitor.name} never reported {self.wanted}")

    async def moved(self, since: float) -> Mapping[str, Value] | None:
        """The first report already received from `since` (loop time) of the monitor away from
        the value written; None if none."""
        return await self.probe.state(
            self.monitor.name, lambda v: not self.at_wanted(v), since=since, wait=0
        )

    def latest(self) -> str:
        """The monitor's newest report, for a failure's text."""
        latest = self.probe.states.get(self.monitor.name)
        return "nothing" if latest is None else str(dict(latest[1]))


async def drive(ctx: Context, where: Callable[[Device], bool] = lambda _: True) -> Driven:
    """A session of the core's endpoint writing a `visible` value to an effector with a monitor
    (`monitored`: `where` holds of the effector; NotApplicable when the model has none)."""
    probe = await open_probe(ctx)
    model = probe.model
    effector, monitor = monitored(model, where)
    opened = await probe.open_session()
    wanted = {f.name: visible(f) for f in effector.fields}
    for module in modules_of(model, effector, monitor):
        probe.session.set_active(module.name, True)
    probe.session.write(effector.name, wanted)
    probe.session.set_active(monitor.name, True)
    return Driven(probe, opened, effector, monitor, wanted)
