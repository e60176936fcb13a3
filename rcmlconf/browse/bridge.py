"""One page's bridge to its robots: a `RobotSession` for each session href of the panel, the
page's messages to them, and everything they have for the page in one `Outbox`.

Every page has sessions of its own, as every RCML browser has (paper Fig. 3: two browsers on one
robot are two sessions; each sees the other's writes, and only one holds the privilege).
"""

from __future__ import annotations

import asyncio
import logging

from rcmlconf.browse.links import RobotLinks
from rcmlconf.browse.messages import Action, Malformed, parse_message
from rcmlconf.browse.outbox import Outbox
from rcmlconf.browse.panel import Panel
from rcmlconf.browse.robot import RobotSession
from rcmlconf.rcml.url import RctpUrl

log = logging.getLogger("rcmlconf.browse")


class Bridge:
    def __init__(
        self,
        panel: Panel,
        links: dict[str, RobotLinks],
        urls: dict[str, RctpUrl],
        timeout: float,
        name: str = "page",
    ) -> None:
        """`urls`: where each session href's robot is served; `name` the page in log lines."""
        self.panel = panel
        self.name = name
        self.outbox = Outbox()
        self.outbox.note("panel", **panel.describe())
        self._widgets = panel.widgets
        self.sessions = {
            href: RobotSession(
                links[href],
                urls[href],
                tuple(w for w in self._widgets.values() if w.link and w.link.robot == href),
                self.outbox,
                timeout,
            )
            for href in panel.robots
        }

    async def run(self) -> None:
        """Until cancelled; every session then says BYE."""
        tasks = [asyncio.ensure_future(s.run()) for s in self.sessions.values()]
        try:
            await asyncio.gather(*tasks)
        finally:
            for task in tasks:
                task.cancel()
            await asyncio.gather(*tasks, return_exceptions=True)

    def receive(self, data: str | bytes) -> None:
        """A message of the page: applied, or refused (logged, and the page told why)."""
        try:
            message = parse_message(data, self._widgets)
        except Malformed as exc:
            log.warning("%s: refused a message: %s", self.name, exc)
            self.outbox.note("refused", reason=str(exc))
            return
        widget = message.widget
        if isinstance(message, Action):
            for href in widget.robots:
                self.sessions[href].action(widget)
        else:
            assert widget.link is not None  # parse_message: an input names a widget that writes
            self.sessions[widget.link.robot].input(message)
