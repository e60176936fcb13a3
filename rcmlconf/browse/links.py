"""The one-way links of a panel (paper §4, Fig. 2) gathered per robot: which access nodes its
session sets up and in which mode, at what pace the page is told, and which nodes it READs.

A widget reads by its node's access method (R-RXID-29): a stream access's data at the access's
interval, an event access's by the server's data-change WRITEs (D-RCTP-27: SETUP and GO when the
window opens, then one READ for the state, since GO sends nothing), a normal access's by READ
every NORMAL_READ_EVERY seconds. A stream access starts when the window opens only when the RXID's
`<access autoStart="true">` asks (D-RXID-8), or later by an actionButton (D-RXID-7).
"""

from __future__ import annotations

from dataclasses import dataclass

from rcmlconf.browse.panel import Panel, PanelWidget, session_href
from rcmlconf.rcml.model import AccessNode, AccessType, DataNode, RcmlDocument
from rcmlconf.rxid.model import AccessSetting

#: Seconds between the READs of a normal access's node that a widget shows: the paper gives
#: normal access no pace; half a second follows a display without loading a robot.
NORMAL_READ_EVERY = 0.5


@dataclass(frozen=True, slots=True)
class AccessUse:
    access: AccessNode
    #: A widget shows one of its nodes.
    reads: bool
    #: A widget writes one of its nodes.
    writes: bool
    auto_start: bool
    #: Seconds between the page's updates of its values: an RXID `readInterval` slower than the
    #: RCML's (D-RXID-8), values meanwhile merged, the newest kept; 0: each DATA as it comes.
    pace: float = 0.0

    @property
    def path(self) -> str:
        return self.access.path

    @property
    def streams(self) -> bool:
        return self.access.type is AccessType.STREAM

    @property
    def starts(self) -> bool:
        """Set up and started when the window opens."""
        return self.auto_start or (self.access.type is AccessType.EVENT and self.reads)

    def mode(self, may_write: bool) -> str | None:
        """A stream's SETUP mode (D-RCTP-18): the directions the panel uses, writing only when
        `may_write` (the session holds the privilege); None when it would use none."""
        # Any use of an access with readable nodes reads them: the panel shows the robot, and
        # a node the user has not moved is written back as the robot has it (`robot`).
        reads = bool(self.access.readable()) and (self.reads or self.writes or self.auto_start)
        writes = self.writes and may_write
        if reads and writes:
            return "both"
        return "write" if writes else "read" if reads else None


@dataclass(frozen=True, slots=True)
class RobotLinks:
    robot: str
    model: RcmlDocument
    #: Event and stream accesses the panel links to or sets, by path.
    accesses: dict[str, AccessUse]
    #: Data nodes of normal accesses a widget shows.
    polled: tuple[DataNode, ...]


def robot_links(panel: Panel) -> dict[str, RobotLinks]:
    """Session href -> what its session does."""
    uses: dict[str, dict[str, AccessUse]] = {href: {} for href in panel.robots}
    polled: dict[str, dict[str, DataNode]] = {href: {} for href in panel.robots}
    for window in panel.windows:
        for setting in window.window.accesses:
            href = session_href(window.sessions, setting.session)
            access = panel.robots[href].node(setting.data_path)
            assert isinstance(access, AccessNode), "R-RXID-9: validated"
            _merge(uses[href], _from_setting(access, setting))
        for widget in window.widgets:
            _add_widget(widget, uses, polled)
    return {
        href: RobotLinks(href, model, uses[href], tuple(polled[href].values()))
        for href, model in panel.robots.items()
    }


def _add_widget(
    widget: PanelWidget,
    uses: dict[str, dict[str, AccessUse]],
    polled: dict[str, dict[str, DataNode]],
) -> None:
    link = widget.link
    if link is None:
        return
    if link.access.type is AccessType.NORMAL:
        if link.reads:
            polled[link.robot][link.node.path] = link.node
        return
    _merge(uses[link.robot], AccessUse(link.access, link.reads, link.writes, auto_start=False))


def _from_setting(access: AccessNode, setting: AccessSetting) -> AccessUse:
    # D-RXID-8: only an RXID `readInterval` slower than the RCML's paces the page. The server
    # already sends at the RCML's; pacing at it too held every DATA that came a little early
    # until the next tick (10 ms at the median) and merged a third of them away (issue 20).
    asked = setting.read_interval or 0.0
    pace = asked if asked > (access.read_interval or 0.0) else 0.0
    return AccessUse(access, reads=False, writes=False, auto_start=setting.auto_start, pace=pace)


def _merge(uses: dict[str, AccessUse], use: AccessUse) -> None:
    old = uses.get(use.path)
    if old is None:
        uses[use.path] = use
        return
    uses[use.path] = AccessUse(
        use.access,
        old.reads or use.reads,
        old.writes or use.writes,
        old.auto_start or use.auto_start,
        max(old.pace, use.pace),
    )
