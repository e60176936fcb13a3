"""Walk an RXID 2.0 tree: report every broken rule (specs/rxid-2.0.md §3) and build the model.

Links are checked against the RCML each session names, which the caller's resolver supplies
(D-RXID-3: the resolver decides what may be read; this module never touches a file).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TypeVar

from rcmlconf.errors import ValueTextError
from rcmlconf.markup.document import NAMESPACE_SEPARATOR, XmlElement
from rcmlconf.markup.lexical import closest
from rcmlconf.markup.structure import Attributes, Checker
from rcmlconf.rcml.model import (
    AccessNode,
    AccessType,
    DataNode,
    GroupNode,
    Permission,
    RcmlDocument,
)
from rcmlconf.rxid.model import AccessSetting, RxidDocument, Session, WidgetElement, Window
from rcmlconf.rxid.schema import ELEMENTS
from rcmlconf.rxid.sessions import Broken, Resolver, SessionTarget, Unresolved
from rcmlconf.rxid.widgets import ACTIONS, WIDGETS, Widget
from rcmlconf.values import DATA_TYPES, Scalar, parse_value_text

_N = TypeVar("_N", AccessNode, DataNode)
_STREAMING = (AccessType.EVENT, AccessType.STREAM)
_WRITTEN = ("value", "releaseValue", "onValue", "offValue")
_FLOAT64 = DATA_TYPES["float64"]


def load_rxid(checker: Checker, resolve: Resolver) -> RxidDocument | None:
    """The document's model, or None when the checker recorded any error."""
    return _Walk(checker, resolve).document(checker.document.root)


def load(checker: Checker, base_dir: Path | None, resolve: Resolver) -> RxidDocument | None:
    """The validator's entry point (`validate.languages`): links resolve through `resolve`."""
    return load_rxid(checker, resolve)


@dataclass(slots=True)
class _Scope:
    """The sessions of one window: what a linking element's `session` may name."""

    by_name: dict[str, SessionTarget | None]
    count: int
    only: SessionTarget | None


class _Walk:
    def __init__(self, checker: Checker, resolve: Resolver) -> None:
        self.check = checker
        self.resolve = resolve
        self.ids: set[str] = set()

    def document(self, root: XmlElement) -> RxidDocument | None:
        attrs = self.check.attributes(root, ELEMENTS["rxid"])
        windows = [self._window(w) for w in self.check.children(root, ELEMENTS["rxid"])]
        if not windows:
            self.check.error("R-RXID-3", root, "<rxid> holds no window")
        if self.check.error_count:
            return None
        return RxidDocument(tuple(windows), attrs.text("title"))

    def _id(self, element: XmlElement, attrs: Attributes) -> None:
        identifier = attrs.text("id")
        if identifier is None:
            return
        if identifier in self.ids:
            self.check.error("R-RXID-22", element, f"id {identifier!r} is used twice", "id")
        self.ids.add(identifier)

    # -- windows and sessions --------------------------------------------------------------------

    def _window(self, element: XmlElement) -> Window:
        spec = ELEMENTS["window"]
        attrs = self.check.attributes(element, spec)
        self._id(element, attrs)
        children = self.check.children(element, spec)
        session_elements = [c for c in children if c.tag == "session"]
        if not session_elements:
            self.check.error(
                "R-RXID-4",
                element,
                "<window> has no <session>",
                hint='add <session href="robot.rcml"/> naming the robot',
            )
        scope, sessions = self._sessions(session_elements)
        accesses: list[AccessSetting] = []
        widgets: list[WidgetElement] = []
        for child in children:
            if child.tag == "access":
                access = self._access(child, scope)
                if access is not None:
                    accesses.append(access)
            elif child.tag != "session":
                widgets.append(self._widget(child, scope))
        return Window(
            tuple(sessions), tuple(accesses), tuple(widgets), attrs.text("title"), _texts(element)
        )

    def _sessions(self, elements: list[XmlElement]) -> tuple[_Scope, list[Session]]:
        spec = ELEMENTS["session"]
        scope = _Scope({}, len(elements), None)
        sessions = []
        for element in elements:
            attrs = self.check.attributes(element, spec)
            self.check.leaf(element, spec)
            name, href = attrs.text("name"), attrs.text("href")
            if len(elements) > 1 and element.attrs.get("name") is None:
                self.check.error(
                    "R-RXID-6",
                    element,
                    f"this window has {len(elements)} sessions: each needs a name",
                )
            if name is not None and name in scope.by_name:
                self.check.error(
                    "R-RXID-6", element, f"another session of this window is named {name!r}", "name"
                )
            target = self._resolve(element, href) if href is not None else None
            if name is not None and name not in scope.by_name:  # a duplicate is reported above
                scope.by_name[name] = target
            scope.only = target
            if href is not None:
                sessions.append(Session(href, name))
        return scope, sessions

    def _resolve(self, element: XmlElement, href: str) -> SessionTarget:
        target = self.resolve(href)
        if isinstance(target, Unresolved):
            self.check.warning(
                "R-RXID-10",
                element,
                f"links through {href!r} are not checked: {target.reason}",
                "href",
            )
        elif isinstance(target, Broken):
            self.check.error("R-RXID-11", element, f"{href!r}: {target.reason}", "href")
        return target

    def _rcml(self, element: XmlElement, attrs: Attributes, scope: _Scope) -> RcmlDocument | None:
        """The RCML the element links into, when its session names one that could be checked."""
        name = attrs.text("session")
        if name is not None:
            if name not in scope.by_name:
                self.check.error(
                    "R-RXID-7", element, f"no session of this window is named {name!r}", "session"
                )
                return None
            target = scope.by_name[name]
        elif element.attrs.get("session") is not None:
            return None  # present but malformed: already reported
        elif scope.count > 1:
            self.check.error(
                "R-RXID-7",
                element,
                f"this window has {scope.count} sessions: say which with session=",
            )
            return None
        else:
            target = scope.only
        return target if isinstance(target, RcmlDocument) else None

    def _lookup(
        self, element: XmlElement, rcml: RcmlDocument, path: str, attribute: str
    ) -> GroupNode | AccessNode | DataNode | None:
        node = rcml.node(path)
        if node is None:
            parent_path, _, name = path.rpartition("/")
            close = closest(name, (child.name for child in rcml.children_of(parent_path)))
            self.check.error(
                "R-RXID-9",
                element,
                f"{path} is not a node of {rcml.site}",
                attribute,
                f"did you mean {parent_path}/{close}?" if close else None,
            )
        return node

    def _linked(
        self,
        element: XmlElement,
        attrs: Attributes,
        scope: _Scope,
        path: str,
        kind: type[_N],
        expected: str,
    ) -> _N | None:
        """The node of `kind` that `dataPath` names in the element's session (R-RXID-9).

        None when there is none, or when the session's RCML could not be had to look.
        """
        rcml = self._rcml(element, attrs, scope)
        node = self._lookup(element, rcml, path, "dataPath") if rcml else None
        if node is None or isinstance(node, kind):
            return node
        self.check.error(
            "R-RXID-9", element, f"{path} is {_kind(node)} node; {expected}", "dataPath"
        )
        return None

    # -- access ----------------------------------------------------------------------------------

    def _access(self, element: XmlElement, scope: _Scope) -> AccessSetting | None:
        spec = ELEMENTS["access"]
        attrs = self.check.attributes(element, spec)
        self.check.leaf(element, spec)
        path = attrs.text("dataPath")
        if path is None:
            return None
        node = self._linked(
            element, attrs, scope, path, AccessNode, "<access> names an access node"
        )
        if node is not None:
            self._intervals(element, attrs, node)
        return AccessSetting(
            path,
            attrs.text("session"),
            attrs.number("readInterval"),
            attrs.number("writeInterval"),
            attrs.text("autoStart") == "true",
        )

    def _intervals(self, element: XmlElement, attrs: Attributes, node: AccessNode) -> None:
        for name, ours in (
            ("readInterval", node.read_interval),
            ("writeInterval", node.write_interval),
        ):
            asked = attrs.number(name)
            if asked is None:
                continue
            if node.type is not AccessType.STREAM or ours is None:
                self.check.warning(
                    "R-RXID-26", element, f"{node.path} has no {name} to slow down", name
                )
            elif asked < ours:
                self.check.error(
                    "R-RXID-25",
                    element,
                    f"{name} {asked:g} s is shorter than the RCML's {ours:g} s",
                    name,
                    "RCML intervals are the shortest a server sends or accepts (D-RCML-6)",
                )

    # -- widgets ---------------------------------------------------------------------------------

    def _widget(self, element: XmlElement, scope: _Scope) -> WidgetElement:
        widget = WIDGETS[element.tag]
        spec = ELEMENTS[element.tag]
        attrs = self.check.attributes(element, spec)
        self._id(element, attrs)
        item_elements = self.check.children(element, spec)
        items = [self._item(item) for item in item_elements]
        if widget.items and not item_elements:
            self.check.error("R-RXID-20", element, f"<{element.tag}> holds no <item>")
        path = attrs.text("dataPath")
        if element.tag == "actionButton":
            path = self._action(element, attrs, scope)
        elif widget.linked and path is not None:
            data = self._linked(element, attrs, scope, path, DataNode, "widgets link to data nodes")
            # Values are checked against the node only when the widget can link to it at all.
            if data is not None and not self._link(element, widget, attrs, data):
                data = None
            self._values(element, widget, attrs, item_elements, items, data)
        return WidgetElement(
            element.tag,
            path,
            attrs.text("session"),
            _texts(element),
            tuple(i for i in items if i is not None),
        )

    def _item(self, element: XmlElement) -> tuple[str, str] | None:
        spec = ELEMENTS["item"]
        attrs = self.check.attributes(element, spec)
        self.check.leaf(element, spec)
        caption, value = attrs.text("caption"), attrs.text("value")
        return (caption, value) if caption is not None and value is not None else None

    def _link(self, element: XmlElement, widget: Widget, attrs: Attributes, node: DataNode) -> bool:
        """R-RXID-12, -13, -16: direction and type of the link; whether the type fits."""
        writes = widget.writes and attrs.text("readOnly") != "true"
        if writes and Permission.WRITE not in node.permission:
            self.check.error(
                "R-RXID-12",
                element,
                f"<{element.tag}> writes, but {node.path} is not writable "
                f"(permission {node.permission.to_text()})",
                "dataPath",
                'add readOnly="true" to show it without writing' if widget.reads else None,
            )
        if not writes and Permission.READ not in node.permission:
            self.check.error(
                "R-RXID-13",
                element,
                f"<{element.tag}> only reads, but {node.path} is not readable "
                f"(permission {node.permission.to_text()})",
                "dataPath",
            )
        if node.type.base.kind not in widget.kinds or (node.type.is_array and not widget.arrays):
            self.check.error(
                "R-RXID-16",
                element,
                f"<{element.tag}> cannot show a {node.type} node ({node.path})",
                "dataPath",
            )
            return False
        return True

    def _values(
        self,
        element: XmlElement,
        widget: Widget,
        attrs: Attributes,
        item_elements: list[XmlElement],
        items: list[tuple[str, str] | None],
        node: DataNode | None,
    ) -> None:
        """R-RXID-17, -19, -21: the values a widget writes, its range and its items."""
        for name in _WRITTEN:
            text = attrs.text(name)
            if text is not None and node is not None:
                self._value(element, name, text, node)
        seen: set[Scalar] = set()
        for item_element, item in zip(item_elements, items, strict=True):
            if item is None:
                continue
            value = self._value(item_element, "value", item[1], node) if node else item[1]
            if value is None:
                continue
            if value in seen:
                self.check.warning(
                    "R-RXID-21",
                    item_element,
                    f"another item already has value {item[1]!r}",
                    "value",
                )
            seen.add(value)
        if widget.ranged:
            self._range(element, attrs, node)

    def _value(self, element: XmlElement, name: str, text: str, node: DataNode) -> Scalar | None:
        """A value the widget writes, as a value of the node's type within its range."""
        try:
            value = parse_value_text(node.type.base, text, node.type.size)
        except ValueTextError as exc:
            self.check.error("R-RXID-17", element, f"{name}: {exc} (for {node.path})", name)
            return None
        problem = node.out_of_range(value)
        if problem is not None:
            self.check.error("R-RXID-17", element, f"{name}: {problem}", name)
        return value

    def _range(self, element: XmlElement, attrs: Attributes, node: DataNode | None) -> None:
        low = self._bound(element, attrs, "min", node)
        high = self._bound(element, attrs, "max", node)
        # A bound written but malformed has been reported already; only absent ones count here.
        missing = [
            n
            for n, v in (("min", low), ("max", high))
            if v is None and element.attrs.get(n) is None
        ]
        if node is not None and missing:
            self.check.error(
                "R-RXID-19",
                element,
                f"<{element.tag}> has no {' and '.join(missing)}, and {node.path} declares none",
            )
        if low is not None and high is not None and not low < high:
            self.check.error(
                "R-RXID-19", element, f"min {low:g} is not less than max {high:g}", "min"
            )

    def _bound(
        self, element: XmlElement, attrs: Attributes, name: str, node: DataNode | None
    ) -> float | None:
        text = attrs.text(name)
        if text is None:
            if node is None:
                return None
            declared = node.minimum if name == "min" else node.maximum
            return None if declared is None else float(declared)
        if node is not None:
            value = self._value(element, name, text, node)
        else:
            try:
                value = parse_value_text(_FLOAT64, text)
            except ValueTextError as exc:
                self.check.error("R-RXID-17", element, f"{name}: {exc}", name)
                return None
        return float(value) if isinstance(value, int | float) else None

    # -- actionButton ----------------------------------------------------------------------------

    def _action(self, element: XmlElement, attrs: Attributes, scope: _Scope) -> str | None:
        """R-RXID-24 and R-RXID-9 for actionButton targets (D-RXID-7)."""
        action, target = attrs.text("action"), attrs.text("target")
        if action is None:
            return target
        if not ACTIONS[action]:
            for name in ("target", "session"):
                if element.attrs.get(name) is not None:
                    self.check.error(
                        "R-RXID-24",
                        element,
                        f"action {action!r} applies to the whole session: no {name}",
                        name,
                    )
            return None
        if target is None:
            if element.attrs.get("target") is None:
                self.check.error("R-RXID-24", element, f"action {action!r} needs a target path")
            return None
        rcml = self._rcml(element, attrs, scope)
        if rcml is None:
            return target
        streaming = action not in ("acquire", "release")
        if target == "/":
            if streaming:
                self.check.error(
                    "R-RXID-9",
                    element,
                    f"action {action!r} applies to an access node, not to '/'",
                    "target",
                )
            return target
        node = self._lookup(element, rcml, target, "target")
        if (
            streaming
            and node is not None
            and not (isinstance(node, AccessNode) and node.type in _STREAMING)
        ):
            what = f"a {node.type.value} access" if isinstance(node, AccessNode) else _kind(node)
            self.check.error(
                "R-RXID-9",
                element,
                f"action {action!r} applies to an event or stream access node; {target} is "
                f"{what} node",
                "target",
            )
        return target


def _texts(element: XmlElement) -> dict[str, str]:
    """An element's attributes as written, but those of other namespaces."""
    return {k: v for k, v in element.attrs.items() if NAMESPACE_SEPARATOR not in k}


def _kind(node: GroupNode | AccessNode | DataNode) -> str:
    """'a group', 'an access' or 'a data', for messages."""
    return {GroupNode: "a group", AccessNode: "an access", DataNode: "a data"}[type(node)]
