"""An RXID document and its robots' RCML as what the page draws: windows of widgets, each widget
with its geometry, its texts and, for a linked one, the node it reads or writes.

The documents are valid (`sources`): every link names a node of the right kind and type
(R-RXID-9, -16), so building this cannot fail. What a widget does follows the R/W table
(D-RXID-1) and the node's permission (D-RXID-5): an R/W widget on a write-only node writes and
shows nothing; `readOnly="true"` makes it a display.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from urllib.parse import urljoin

from rcmlconf.rcml.model import AccessNode, DataNode, Permission, RcmlDocument
from rcmlconf.reference.client.files import is_http_url
from rcmlconf.rxid.model import RxidDocument, WidgetElement, Window
from rcmlconf.rxid.widgets import ACTIONS, WIDGETS
from rcmlconf.values import Kind, Value, parse_value_text
from rcmlconf.values.shown import value_text

_GEOMETRY = ("x", "y", "width", "height")
#: D-RXID-6: what a checkbox writes when the RXID does not say, by the node's kind.
_CHECKBOX = {Kind.BOOL: ("true", "false"), Kind.INTEGER: ("1", "0")}
#: A floating-point slider without `step` moves in this many steps from end to end.
_FLOAT_STEPS = 100


@dataclass(frozen=True, slots=True)
class Link:
    """The node a widget is linked to (D-RXID-4) and which way (D-RXID-1, D-RXID-5)."""

    #: The session href of the robot: one reference-client session each.
    robot: str
    node: DataNode
    access: AccessNode
    reads: bool
    writes: bool


@dataclass(frozen=True, slots=True)
class PanelWidget:
    #: The page's name for it: `w0`, `w1`, ... in document order.
    key: str
    element: WidgetElement
    link: Link | None
    #: An actionButton's robots: its session's, or all the window's for connect and bye.
    robots: tuple[str, ...] = ()
    #: A scroll's or slider's range and step (D-RXID-6).
    bounds: tuple[float, float, float] | None = None

    @property
    def kind(self) -> str:
        return self.element.kind

    def attribute(self, name: str) -> str | None:
        return self.element.attributes.get(name)


@dataclass(frozen=True, slots=True)
class PanelWindow:
    window: Window
    widgets: tuple[PanelWidget, ...]
    #: The window's sessions: name (None for a lone unnamed one) -> href.
    sessions: dict[str | None, str]


@dataclass(frozen=True, slots=True)
class Panel:
    title: str
    windows: tuple[PanelWindow, ...]
    #: Session href -> the robot's RCML.
    robots: dict[str, RcmlDocument]
    #: The RXID's URL when it came from one: relative hrefs of `html`, `netmeeting` and
    #: `background` resolve against it; from a file, only absolute http(s) ones are shown.
    base_url: str | None = None

    @property
    def widgets(self) -> dict[str, PanelWidget]:
        return {w.key: w for window in self.windows for w in window.widgets}

    def describe(self) -> dict[str, object]:
        """The panel as the page's `panel` message carries it (docs/browse.md)."""
        return {
            "title": self.title,
            "robots": [
                {"robot": href, "title": model.title or href, "site": str(model.site)}
                for href, model in self.robots.items()
            ],
            "windows": [self._window(w) for w in self.windows],
        }

    def _window(self, window: PanelWindow) -> dict[str, object]:
        attributes = window.window.attributes
        return {
            "id": attributes.get("id"),
            "title": window.window.title,
            **_geometry(attributes),
            "background": self.shown_url(attributes.get("background")),
            "widgets": [self._widget(w) for w in window.widgets],
        }

    def _widget(self, widget: PanelWidget) -> dict[str, object]:
        described: dict[str, object] = {
            "key": widget.key,
            "kind": widget.kind,
            "id": widget.attribute("id"),
            "caption": widget.attribute("caption"),
            **_geometry(widget.element.attributes),
        }
        link = widget.link
        if link is not None:
            described |= {
                "robot": link.robot,
                "path": link.node.path,
                "reads": link.reads,
                "writes": link.writes,
            }
        if widget.bounds is not None:
            low, high, step = widget.bounds
            described |= {"min": low, "max": high, "step": step}
            described["orientation"] = widget.attribute("orientation") or "horizontal"
        if widget.element.items:
            described["items"] = [
                {"caption": c, "value": normal(widget, v)} for c, v in widget.element.items
            ]
        if widget.kind == "checkbox":
            described["on"], described["off"] = (normal(widget, v) for v in checkbox_values(widget))
        if widget.kind in ("html", "netmeeting"):
            described["href"] = widget.attribute("href")
            described["src"] = self.shown_url(widget.attribute("href"))
        if widget.kind == "actionButton":
            described |= {
                "action": widget.attribute("action"),
                "target": widget.element.path,
                "robots": list(widget.robots),
            }
        return described

    def shown_url(self, href: str | None) -> str | None:
        """The http(s) URL the page may load for `href`, or None (D-RXID-9: never fetched by
        rcmlconf itself; the user's browser loads it, as any web page's image or frame)."""
        if href is None:
            return None
        try:
            url = urljoin(self.base_url, href) if self.base_url else href
        except ValueError:
            return None
        return url if is_http_url(url) else None


def build_panel(
    rxid: RxidDocument, robots: dict[str, RcmlDocument], base_url: str | None = None
) -> Panel:
    """The panel of a valid RXID whose every session href has its RCML in `robots`."""
    count = 0
    windows = []
    for window in rxid.windows:
        sessions = {s.name: s.href for s in window.sessions}
        widgets = []
        for element in window.widgets:
            widgets.append(_widget(f"w{count}", element, window, sessions, robots))
            count += 1
        windows.append(PanelWindow(window, tuple(widgets), sessions))
    title = rxid.title or next((w.title for w in rxid.windows if w.title), None) or "RXID panel"
    return Panel(title, tuple(windows), dict(robots), base_url)


def session_href(sessions: dict[str | None, str], name: str | None) -> str:
    """The href of the session `name` names, or of a window's only session (D-RXID-2)."""
    if name is None:
        assert len(sessions) == 1, "R-RXID-7: validated"
        return next(iter(sessions.values()))
    return sessions[name]


def _widget(
    key: str,
    element: WidgetElement,
    window: Window,
    sessions: dict[str | None, str],
    robots: dict[str, RcmlDocument],
) -> PanelWidget:
    spec = WIDGETS[element.kind]
    if element.kind == "actionButton":
        action = element.attributes["action"]
        if ACTIONS[action]:
            return PanelWidget(key, element, None, (session_href(sessions, element.session),))
        return PanelWidget(key, element, None, tuple(dict.fromkeys(sessions.values())))
    if not spec.linked or element.path is None:
        return PanelWidget(key, element, None)
    href = session_href(sessions, element.session)
    model = robots[href]
    node = model.node(element.path)
    access = model.node(element.path.rsplit("/", 1)[0] or "/")
    assert isinstance(node, DataNode), "R-RXID-9: validated"
    assert isinstance(access, AccessNode), "D-RCML-2: data lives in access nodes"
    read_only = element.attributes.get("readOnly") == "true"
    link = Link(
        href,
        node,
        access,
        reads=spec.reads and Permission.READ in node.permission,
        writes=spec.writes and not read_only and Permission.WRITE in node.permission,
    )
    bounds = _bounds(element, node) if spec.ranged else None
    return PanelWidget(key, element, link, bounds=bounds)


def _bounds(element: WidgetElement, node: DataNode) -> tuple[float, float, float]:
    """D-RXID-6: min and max, the widget's or else the node's (R-RXID-19: one or the other is
    there); step, else 1 for an integer node and a hundredth of the range for a float one."""
    low = _number(element, "min", node, node.minimum)
    high = _number(element, "max", node, node.maximum)
    step_text = element.attributes.get("step")
    if step_text is not None:
        step = float(step_text)
    elif node.type.base.kind is Kind.INTEGER:
        step = 1.0
    else:
        step = (high - low) / _FLOAT_STEPS
    return low, high, step


def _number(element: WidgetElement, name: str, node: DataNode, declared: float | None) -> float:
    text = element.attributes.get(name)
    if text is None:
        assert declared is not None, "R-RXID-19: validated"
        return float(declared)
    value = parse_value_text(node.type.base, text, node.type.size)
    assert isinstance(value, int | float)
    return float(value)


def checkbox_values(widget: PanelWidget) -> tuple[str, str]:
    """(onValue, offValue) of a checkbox (D-RXID-6)."""
    assert widget.link is not None
    on, off = _CHECKBOX.get(widget.link.node.type.base.kind, ("1", "0"))
    return widget.attribute("onValue") or on, widget.attribute("offValue") or off


def normal(widget: PanelWidget, text: str) -> str:
    """A value the RXID writes as text, in the form the page is sent values (`01` is `1`), so
    that the page can tell which item or state a value of the robot is."""
    if widget.link is None:
        return text
    node = widget.link.node
    return shown(node, parse_value_text(node.type.base, text, node.type.size))


def shown(node: DataNode, value: Value) -> str:
    """A node's value as the page shows it: its text form (D-RCML-14), controls escaped."""
    return value_text(node.type, value)


def _geometry(attributes: Mapping[str, str]) -> dict[str, int | None]:
    """D-RXID-9: pixels from the window's top-left corner; absent ones the page chooses."""
    return {
        name: None if (text := attributes.get(name)) is None else int(text) for name in _GEOMETRY
    }
